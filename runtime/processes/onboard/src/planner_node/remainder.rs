//! The answers without a new frame: the remainder of the current plan after a failed unload
//! (the paper's no-retry), with GROP+'s retry of the failed object first when the policy retries.

use super::*;

impl PlannerNode {
    /// GROP+'s retry of `object` from `at_xy` (navigate + unload steps), if the policy retries:
    /// [`planner::grop_plus::retry_goal`] on the last plan's problem, the goals tried for the
    /// object so far excluded.
    pub(super) fn retry_pair(
        &mut self,
        object: usize,
        at_xy: (f64, f64),
    ) -> Option<(TaskStep, TaskStep)> {
        let (objects, problem) = self.last_problem.as_ref()?;
        let local = objects.iter().position(|&o| o == object)?;
        let tried = &self.tried[object];
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let goal = retry_goal(
            &self.planner.config,
            problem,
            local,
            tried,
            at_xy,
            tried.len().saturating_sub(1),
            &mut travel,
        )?;
        let loc = &problem.locations[goal.location];
        let mut nav = TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, 0.0);
        nav.side = i32::from(loc.side.sign());
        let unload = TaskStep::unload(
            object as u32,
            table_side(loc.side),
            loc.target,
            [goal.xy.0, goal.xy.1, goal.yaw_rad],
            // The retry's predicted success: the heatmap value of its cell.
            f64::from(goal.heat_value),
        );
        Some((nav, unload))
    }

    /// The no-retry answer (the paper's): the current plan's unloads of the objects in `left`, in
    /// order, from the request's pose; a station visit only for objects not on board. With
    /// `first` (GROP+'s retry of the failed object) that unload comes first and the failed object
    /// is not repeated from the current plan.
    pub(super) fn publish_remainder(
        &mut self,
        request: &ReplanRequestMsg,
        first: Option<(TaskStep, TaskStep)>,
        left: u64,
        on_board: u64,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let started = Instant::now();
        let Some(current) = self.current.as_ref() else {
            return self.plan_and_publish(request, left, on_board, now);
        };
        let frame_id = current.source_frame_id;
        // Groups of (navigate, unload): first the objects on board (the retry first), then, per
        // trip of the current plan, its objects still at the station (one station visit each).
        let mut groups: Vec<Vec<(TaskStep, TaskStep)>> = vec![first.into_iter().collect()];
        let retried = first.map_or(0, |(_, u)| 1u64 << u.object_index);
        for w in current.steps.windows(2) {
            if w[1].kind() == Ok(TaskStepKind::Load) {
                groups.push(Vec::new());
            }
            if w[1].kind() == Ok(TaskStepKind::Unload)
                && let Ok(o) = w[1].object()
                && left & !retried & (1 << o) != 0
            {
                let group = if on_board & (1 << o) != 0 {
                    0
                } else {
                    groups.len() - 1
                };
                groups[group].push((w[0], w[1]));
            }
        }
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut at = (request.pose[0], request.pose[1]);
        let mut steps = Vec::with_capacity(current.steps.len() + 2);
        let station = (
            self.scene.loading_station.x_m,
            self.scene.loading_station.y_m,
        );
        // The tray's free slots for the trips: what is on board less what the first group
        // unloads (an object given up, or one the current plan does not unload, stays on the
        // tray). None free: the objects still at the station cannot be fetched.
        let unloaded_first = groups[0]
            .iter()
            .filter_map(|(_, u)| u.object().ok())
            .fold(0u64, |m, o| m | (1u64 << o));
        let kept = (request.on_board_mask & !unloaded_first).count_ones() as usize;
        let free = self.capacity.saturating_sub(kept);
        if free == 0 && groups.len() > 1 {
            log::warn!(
                "request {}: the tray stays full ({kept} objects kept on it); the objects at \
                 the station are not planned",
                request.request_id
            );
            groups.truncate(1);
        }
        // A trip of the current plan larger than the tray's free slots becomes several station
        // visits, in the same order.
        let groups: Vec<Vec<(TaskStep, TaskStep)>> = groups
            .into_iter()
            .enumerate()
            .flat_map(|(g, pairs)| {
                if g == 0 || pairs.len() <= free {
                    vec![pairs]
                } else {
                    pairs.chunks(free).map(<[_]>::to_vec).collect()
                }
            })
            .collect();
        let (mut feasibility, mut cost_s) = (0.0, 0.0);
        for (g, pairs) in groups.into_iter().enumerate() {
            let to_load = pairs
                .iter()
                .filter_map(|(_, u)| u.object().ok())
                .fold(0u64, |m, o| m | (1u64 << o))
                & !on_board;
            if g > 0 && to_load == 0 {
                continue;
            }
            if to_load != 0 {
                let cost = travel.travel_time_s(at, station).unwrap_or(no_path_s);
                steps.push(TaskStep::navigate(
                    station.0,
                    station.1,
                    self.station_yaw_rad(),
                    cost,
                ));
                steps.push(TaskStep::load(to_load, station.0, station.1));
                at = station;
            }
            for (mut nav, unload) in pairs {
                nav.travel_cost_s = travel
                    .travel_time_s(at, (nav.x_m, nav.y_m))
                    .unwrap_or(no_path_s);
                at = (nav.x_m, nav.y_m);
                feasibility += unload.feasibility;
                steps.push(nav);
                steps.push(unload);
            }
        }
        for s in &steps {
            cost_s += s.travel_cost_s;
        }
        let utility = self.planner.config.success_bonus_r * feasibility - cost_s;
        self.publish_plan(
            request,
            frame_id,
            &steps,
            (feasibility, cost_s, utility),
            started,
            now,
        )
    }
}
