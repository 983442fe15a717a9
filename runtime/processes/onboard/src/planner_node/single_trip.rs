//! One trip planned from the newest frame: views cut (unknown past the frame's edge), Psi,
//! the task problem, the selected method, the plan's steps; multi-trip requests go on to
//! `multi_trip`.

use super::*;

impl PlannerNode {
    /// Cut + Psi + planner over the objects of `objects_mask` from the request's pose.
    #[allow(
        clippy::too_many_lines,
        reason = "one request planned in order: frame, problem, method, checks, message"
    )]
    pub(super) fn plan_and_publish(
        &mut self,
        request: &ReplanRequestMsg,
        objects_mask: u64,
        on_board: u64,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let started = Instant::now();
        let mut objects_mask = objects_mask;
        let mut objects: Vec<usize> = (0..self.scene.targets.len())
            .filter(|i| objects_mask & (1 << i) != 0)
            .collect();
        if objects.len() > MAX_PROBLEM_OBJECTS {
            return Err(RequestError::TooManyObjects(objects.len()));
        }
        // Objects on the tray that this plan does not unload (given up after a failed unload)
        // keep their slots.
        let free = self.tray_free(request, objects_mask)?;
        // One trip when the tray takes everything (the single-trip planner, exactly as before);
        // otherwise trips, the objects already on board first (delivered before the next
        // station visit).
        let mut single_trip = objects.len() <= free.min(MAX_OBJECTS);
        if !single_trip {
            objects.sort_by_key(|&o| on_board & (1 << o) == 0);
        }
        if objects.is_empty() {
            let frame_id = self.newest_frame.as_ref().map_or(0, |f| f.header.frame_id);
            return self.publish_plan(request, frame_id, &[], (0.0, 0.0, 0.0), started, now);
        }
        let Some(frame) = self.newest_frame.as_ref() else {
            // `step` answers only with a frame; keep the invariant visible.
            return Err(MessageError::NotFinite {
                message: "CameraFrameMsg",
                field: "none received",
                index: 0,
            }
            .into());
        };
        let header = frame.header;
        let pixels = frame.image()?;
        let layout = header.layout()?;
        let mut targets: Vec<[f64; 3]> = objects
            .iter()
            .map(|&i| self.scene.targets[i].as_array())
            .collect();
        let mut m = 2 * objects.len();
        let views: Vec<(f64, Side)> = (0..m)
            .map(|i| (targets[i / 2][0], side_of_location(i)))
            .collect();
        // Views inside the frame are cut together; a view that reaches past the frame's edge
        // is cut alone: wall where it lies outside the room, unknown (read as wall, and no
        // goal) where it lies inside the room but outside the frame.
        let mut inside: Vec<usize> = Vec::with_capacity(m);
        let mut unknown: Vec<(usize, Box<[bool; CROP_CELLS]>, usize)> = Vec::new();
        for (i, &(x, side)) in views.iter().enumerate() {
            let cut_error = |error| RequestError::Cut {
                object: objects[i / 2],
                side,
                error,
            };
            match check_view(&layout, x, side) {
                Ok(()) => inside.push(i),
                Err(CameraError::ViewOutsideFrame { .. }) => {
                    let mut cells = Box::new([false; CROP_CELLS]);
                    let n = cut_view_past_frame(
                        pixels,
                        &layout,
                        &self.scene.room,
                        x,
                        side,
                        &mut self.crops[i],
                        &mut cells,
                    )
                    .map_err(cut_error)?;
                    if n > 0 {
                        unknown.push((i, cells, n));
                    }
                }
                Err(error) => return Err(cut_error(error)),
            }
        }
        if !inside.is_empty() {
            let inside_views: Vec<(f64, Side)> = inside.iter().map(|&i| views[i]).collect();
            let mut crops = vec![[0u8; CROP_CELLS]; inside.len()];
            cut_views(pixels, &layout, &inside_views, &mut crops).map_err(|error| {
                RequestError::Cut {
                    object: objects[inside[0] / 2],
                    side: inside_views[0].1,
                    error,
                }
            })?;
            for (&i, crop) in inside.iter().zip(&crops) {
                self.crops[i] = *crop;
            }
        }
        evaluate_crops(
            &self.scene,
            &self.robot,
            &targets,
            &self.crops[..m],
            self.psi.as_mut(),
            &mut self.heat_buffers[..m],
        )?;
        // Unknown is not free: no goal on a cell the camera did not see. An object whose views
        // keep no cell with a chance is not planned; the node says so on `events` and plans the
        // rest.
        for (i, cells, _) in &unknown {
            for (v, u) in self.heat_buffers[*i]
                .values_mut()
                .iter_mut()
                .zip(cells.iter())
            {
                if *u {
                    *v = 0.0;
                }
            }
        }
        let unknown_of = |i: usize| unknown.iter().find(|(k, _, _)| *k == i).map_or(0, |u| u.2);
        let not_planned: Vec<usize> = (0..objects.len())
            .filter(|&k| {
                let blind = unknown_of(2 * k) + unknown_of(2 * k + 1) > 0;
                let hopeless = (2 * k..2 * k + 2)
                    .all(|i| self.heat_buffers[i].values().iter().all(|&v| v <= 0.0));
                blind && hopeless
            })
            .collect();
        for &k in not_planned.iter().rev() {
            let object = objects[k];
            let detail = format!(
                "object {object} not planned: view cells unknown past the camera frame (near {}, far {}), no goal left",
                unknown_of(2 * k),
                unknown_of(2 * k + 1)
            );
            log::warn!("request {}: {detail}", request.request_id);
            let mut event = EventMsg::new(EventKind::NotPlanned, duration_ns(now), &detail)
                .with_source(ProcessRole::Planner);
            event.step_index = object as u32;
            if let Err(error) = self.events.publish(&event) {
                log::warn!("event: {error}");
            }
            objects.remove(k);
            targets.remove(k);
            self.crops.copy_within(2 * k + 2..m, 2 * k);
            self.heat_buffers[2 * k..m].rotate_left(2);
            m -= 2;
            objects_mask &= !(1u64 << object);
        }
        if objects.is_empty() {
            return self.publish_plan(request, header.frame_id, &[], (0.0, 0.0, 0.0), started, now);
        }
        single_trip = single_trip || objects.len() <= free.min(MAX_OBJECTS);
        let heatmaps = &mut self.heat_buffers[..m];
        let mut problem = TaskProblem::from_heatmaps(&self.scene, &self.robot, &targets, heatmaps);
        let pose_xy = (request.pose[0], request.pose[1]);
        problem.start_xy = pose_xy;
        let seed = match request.reason()? {
            ReplanReason::MissionStart => self.seed,
            _ => world::generate::mix_seed(self.seed, 0x7265_706c, request.request_id),
        };
        let (steps, totals, feasibility_of) = if single_trip {
            let all_on_board = objects.iter().all(|&o| on_board & (1 << o) != 0);
            if all_on_board {
                problem.station_xy = pose_xy;
            }
            let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
            let decision = self.planner.plan(&problem, &mut travel, seed)?;
            self.last_problem = Some((objects.clone(), problem));
            let load_mask = if all_on_board {
                0
            } else {
                objects_mask & !on_board
            };
            let steps = self.steps_of(
                &decision,
                &objects,
                &targets,
                load_mask,
                pose_xy,
                &mut travel,
            );
            log::debug!("{}", decision.explain(3));
            let feasibility_of: Vec<f64> =
                decision.locations.iter().map(|l| l.feasibility).collect();
            (
                steps,
                (decision.feasibility, decision.cost_s, decision.utility),
                feasibility_of,
            )
        } else {
            let planned = self.plan_trips(&objects, &targets, on_board, pose_xy, seed, free)?;
            self.last_problem = Some((objects.clone(), problem));
            planned
        };
        let frame_id = header.frame_id;
        // Heatmaps first: a reader of the plan finds the heatmaps it came from. More than 12
        // objects take several messages of MAX_HEATMAPS locations, same source frame.
        for first in (0..m).step_by(MAX_HEATMAPS) {
            let chunk = &self.heat_buffers[first..m.min(first + MAX_HEATMAPS)];
            self.heatmaps.publish_with(|msg| {
                msg.stamp_ns = duration_ns(now);
                msg.source_frame_id = frame_id;
                msg.count = chunk.len() as u32;
                for (k, (slot, h)) in msg.locations.iter_mut().zip(chunk).enumerate() {
                    let i = first + k;
                    slot.object_index = objects[i / 2] as u32;
                    slot.side = i32::from(side_of_location(i).sign());
                    slot.target_m = targets[i / 2];
                    slot.feasibility = feasibility_of[i];
                    slot.values.copy_from_slice(h.values());
                }
            })?;
        }
        self.publish_plan(request, frame_id, &steps, totals, started, now)
            .map(|a| Answer {
                replanned: true,
                ..a
            })
    }

    /// The plan's steps: station visit and load (if anything must be loaded), then per unload
    /// the navigation to its goal (leg cost from the grid) and the unload.
    pub(super) fn steps_of(
        &self,
        decision: &PlannedTask,
        objects: &[usize],
        targets: &[[f64; 3]],
        load_mask: u64,
        start_xy: (f64, f64),
        travel: &mut dyn TravelTime,
    ) -> Vec<TaskStep> {
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut leg =
            |from: (f64, f64), to: (f64, f64)| travel.travel_time_s(from, to).unwrap_or(no_path_s);
        let mut steps = Vec::with_capacity(2 + 2 * objects.len());
        let mut at = start_xy;
        if load_mask != 0 {
            let station = (
                self.scene.loading_station.x_m,
                self.scene.loading_station.y_m,
            );
            steps.push(TaskStep::navigate(
                station.0,
                station.1,
                self.station_yaw_rad(),
                leg(at, station),
            ));
            steps.push(TaskStep::load(load_mask, station.0, station.1));
            at = station;
        }
        for u in &decision.plan.unloads {
            let goal = decision.goal_of(u);
            let side = table_side(u.side);
            let mut nav = TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, leg(at, goal.xy));
            nav.side = i32::from(u.side.sign());
            steps.push(nav);
            steps.push(TaskStep::unload(
                objects[u.object] as u32,
                side,
                targets[u.object],
                [goal.xy.0, goal.xy.1, goal.yaw_rad],
                decision.locations[location_index(u.object, u.side)].feasibility,
            ));
            at = goal.xy;
        }
        steps
    }

    /// Heading at the station: facing the loading table.
    pub(super) fn station_yaw_rad(&self) -> f64 {
        let (s, t) = (&self.scene.loading_station, &self.scene.loading_table);
        (t.center_y_m - s.y_m).atan2(t.center_x_m - s.x_m)
    }

    /// Free tray slots for a plan over `objects_mask`: the tray (`carry_capacity`) less the
    /// objects on board (`request.on_board_mask`) that the plan does not unload. None free while
    /// something must be loaded is an error.
    pub(super) fn tray_free(
        &self,
        request: &ReplanRequestMsg,
        objects_mask: u64,
    ) -> Result<usize, RequestError> {
        let kept = (request.on_board_mask & !objects_mask).count_ones() as usize;
        let free = self.capacity.saturating_sub(kept);
        if free == 0 && objects_mask & !request.on_board_mask != 0 {
            return Err(RequestError::TrayFull {
                kept,
                capacity: self.capacity,
            });
        }
        Ok(free.max(1))
    }
}
