//! The node's I/O: the loop on the runtime clock, one cycle's reads (frames, requests), the
//! heartbeat, the dispatch of a request to the planning that answers it, and the plan's message.

use super::*;

impl PlannerNode {
    /// A frame to plan from: there is one, and it is no older than [`MAX_FRAME_AGE`] (a frozen
    /// camera keeps delivering its last picture; the world may have changed since). Reports a
    /// too-old frame once.
    pub(super) fn fresh_frame(&mut self, now: Duration) -> bool {
        let Some(frame) = self.newest_frame.as_ref() else {
            return false;
        };
        // From its stamp and from when it was taken: a frame that stops coming goes stale
        // whatever its stamp says.
        let age = now
            .saturating_sub(Duration::from_nanos(frame.header.stamp_ns))
            .max(now.saturating_sub(self.newest_frame_taken));
        if age <= MAX_FRAME_AGE {
            return true;
        }
        if self.pending.is_some() && self.stale_frame_warned != Some(frame.header.frame_id) {
            self.stale_frame_warned = Some(frame.header.frame_id);
            self.failures += 1;
            let text = format!(
                "camera frame {} is {:.1} s old (at most {:.1} s): not planning from it; waiting for a fresh one",
                frame.header.frame_id,
                age.as_secs_f64(),
                MAX_FRAME_AGE.as_secs_f64()
            );
            log::warn!("{text}");
            self.last_error = Some(text);
        }
        false
    }

    /// Runs the loop until `stop` is set or the clock is lost: every [`CYCLE`] of clock time one
    /// [`step`](Self::step), absolute deadlines (a late cycle does not shift the later ones;
    /// missed cycles are skipped and counted as overruns).
    pub fn run(&mut self, clock: &dyn Clock, stop: &AtomicBool) -> Result<(), PlannerNodeError> {
        clock.wait_turn();
        // On the wall clock the node also wakes the moment a frame or a request arrives (the
        // frame-to-plan latency is then the decision, not the loop's phase); on a simulated
        // clock it runs on its ticks only, which is what makes a mission repeatable.
        let event_driven = !clock.is_simulated();
        let mut next = clock.now();
        while !stop.load(Ordering::Relaxed) {
            if clock.is_lost() {
                log::warn!("the clock is lost; the planner node stops");
                break;
            }
            if event_driven {
                self.frames.clear_wakeups()?;
                self.requests.clear_wakeups()?;
            }
            let now = clock.now();
            self.step(now)?;
            let after = clock.now();
            if after >= next {
                next += CYCLE;
                while next <= after {
                    next += CYCLE;
                    self.overruns += 1;
                }
            }
            if event_driven {
                let fds = [self.frames.wake_fd(), self.requests.wake_fd()];
                if let Err(e) = grop_ipc::wait_any(&fds, next.saturating_sub(clock.now())) {
                    log::warn!("waiting for frames and requests: {e}; sleeping instead");
                    clock.sleep_until(next);
                }
            } else {
                clock.sleep_until(next);
            }
        }
        Ok(())
    }

    /// One cycle at clock time `now`: take the newest frame and request, answer the request if a
    /// frame is there, send the heartbeat when due. Returns the answer if one was published.
    /// Failures to answer are logged and counted, not returned (the node keeps serving).
    pub fn step(&mut self, now: Duration) -> Result<Option<Answer>, PlannerNodeError> {
        while let Some(frame) = self.frames.try_recv()? {
            let stamp = Duration::from_nanos(frame.header.stamp_ns);
            if stamp > now.saturating_add(MAX_FRAME_LEAD) {
                self.frames_refused += 1;
                self.failures += 1;
                let text = format!(
                    "camera frame {} stamped {:.3} s, {:.3} s after now: refused (a stamp in the future)",
                    frame.header.frame_id,
                    stamp.as_secs_f64(),
                    (stamp - now).as_secs_f64()
                );
                log::warn!("{text}");
                self.last_error = Some(text);
                continue;
            }
            self.newest_frame = Some(frame);
            self.newest_frame_taken = now;
        }
        while let Some(request) = self.requests.try_recv()? {
            if let Some(old) = self.pending.replace(*request) {
                log::warn!(
                    "request {} superseded by {} before it was answered",
                    old.request_id,
                    request.request_id
                );
            }
        }
        let mut answer = None;
        let fresh = self.fresh_frame(now);
        let can_answer = self.pending.is_some_and(|r| {
            fresh
                || (r.reason() == Ok(ReplanReason::UnloadFailed)
                    && matches!(self.retry, RetryPolicy::None | RetryPolicy::GropPlus)
                    && self.current.is_some())
        });
        if can_answer {
            if let Some(request) = self.pending.take() {
                match self.answer(&request, now) {
                    Ok(a) => {
                        log::info!(
                            "answered request {} with plan {} ({} steps, {})",
                            a.request_id,
                            a.plan_id,
                            a.step_count,
                            if a.replanned { "planned" } else { "remainder" }
                        );
                        answer = Some(a);
                    }
                    Err(error) => {
                        self.failures += 1;
                        log::error!("request {}: {error}", request.request_id);
                        self.last_error = Some(error.to_string());
                    }
                }
            }
        }
        if self.next_heartbeat.is_none_or(|due| now >= due) {
            self.send_heartbeat(now);
            let due = self.next_heartbeat.unwrap_or(now) + HEARTBEAT_PERIOD;
            self.next_heartbeat = Some(if due <= now {
                now + HEARTBEAT_PERIOD
            } else {
                due
            });
        }
        for result in [
            self.plans.serve_late_subscribers(),
            self.heatmaps.serve_late_subscribers(),
        ] {
            if let Err(error) = result {
                log::warn!("{error}");
            }
        }
        Ok(answer)
    }

    pub(super) fn send_heartbeat(&mut self, now: Duration) {
        self.heartbeat_seq += 1;
        let (seq, overruns) = (self.heartbeat_seq, self.overruns);
        let sent = self.health.publish_with(|beat| {
            beat.seq = seq;
            beat.stamp_ns = duration_ns(now);
            beat.set_role(ProcessRole::Planner);
            beat.pid = std::process::id();
            beat.overruns = overruns;
        });
        if let Err(error) = sent {
            log::warn!("heartbeat: {error}");
        }
    }

    pub(super) fn answer(
        &mut self,
        request: &ReplanRequestMsg,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        let reason = request.reason()?;
        let n = self.scene.targets.len();
        let all = if n >= 64 { u64::MAX } else { (1u64 << n) - 1 };
        let mut remaining = request.remaining_mask & all;
        if remaining == 0 && reason == ReplanReason::MissionStart {
            remaining = all;
        }
        let on_board = request.on_board_mask & remaining;
        let pose = request.pose;
        if !pose.iter().all(|v| v.is_finite()) {
            return Err(MessageError::NotFinite {
                message: "ReplanRequestMsg",
                field: "pose",
                index: 0,
            }
            .into());
        }
        let failed_bit = if (request.failed_object as usize) < n {
            1u64 << request.failed_object
        } else {
            0
        };
        if reason == ReplanReason::MissionStart {
            self.tried.iter_mut().for_each(Vec::clear);
        }
        // GROP+ retries an unload elsewhere when it failed at the table, and when the leg to its
        // standing spot failed (no way in, blocked, stalled): the spot is tried either way.
        if matches!(reason, ReplanReason::UnloadFailed | ReplanReason::LegFailed)
            && self.retry == RetryPolicy::GropPlus
            && failed_bit != 0
            && self.current.is_some()
        {
            let object = request.failed_object as usize;
            self.tried[object].push((request.failed_goal_m[0], request.failed_goal_m[1]));
            if let Some(retry) = self.retry_pair(object, (pose[0], pose[1])) {
                return self.publish_remainder(request, Some(retry), remaining, on_board, now);
            }
        }
        match (reason, self.retry) {
            // A leg that could not be driven to an unload's goal failed that unload (the
            // paper's no-retry: go on with the rest; GROP+ once no other spot is left).
            (
                ReplanReason::UnloadFailed | ReplanReason::LegFailed,
                RetryPolicy::None | RetryPolicy::GropPlus,
            ) if failed_bit != 0 || reason == ReplanReason::UnloadFailed => {
                let left = remaining & !failed_bit;
                if self.current.is_some() {
                    self.publish_remainder(request, None, left, on_board & left, now)
                } else {
                    self.plan_and_publish(request, left, on_board & left, now)
                }
            }
            _ => self.plan_and_publish(request, remaining, on_board, now),
        }
    }

    pub(super) fn publish_plan(
        &mut self,
        request: &ReplanRequestMsg,
        frame_id: u64,
        steps: &[TaskStep],
        (feasibility, cost_s, utility): (f64, f64, f64),
        started: Instant,
        now: Duration,
    ) -> Result<Answer, RequestError> {
        if steps.len() > MAX_TASK_STEPS {
            return Err(MessageError::CountTooLarge {
                message: "TaskPlanMsg",
                field: "steps",
                count: steps.len() as u64,
                capacity: MAX_TASK_STEPS as u64,
            }
            .into());
        }
        // The planner plans how the base docks and backs out; the executive follows.
        let mut steps = steps.to_vec();
        self.docking.annotate(
            &mut steps,
            request.pose,
            request.flags & grop_ipc::REQUEST_AT_TABLE != 0,
        );
        // And the tray: which slot each object rides in, from the tray the request describes.
        crate::tray_plan::assign_slots(
            &mut steps,
            &crate::tray_plan::tray_of(&request.tray),
            self.capacity,
        )?;
        let steps = steps.as_slice();
        self.plan_counter += 1;
        let plan_id = self.plan_counter;
        let reward = self.planner.config.success_bonus_r;
        let object_count = self.scene.targets.len() as u32;
        let decision_us = started.elapsed().as_micros().min(u128::from(u64::MAX)) as u64;
        self.plans.publish_with(|msg| {
            msg.plan_id = plan_id;
            msg.stamp_ns = duration_ns(now);
            msg.source_frame_id = frame_id;
            msg.answers_request = request.request_id;
            msg.utility = utility;
            msg.feasibility = feasibility;
            msg.cost_s = cost_s;
            msg.reward = reward;
            msg.object_count = object_count;
            msg.decision_us = decision_us;
            // Cannot fail: checked above.
            let _ = msg.set_steps(steps);
        })?;
        self.current = Some(CurrentPlan {
            source_frame_id: frame_id,
            steps: steps.to_vec(),
        });
        Ok(Answer {
            request_id: request.request_id,
            plan_id,
            step_count: steps.len(),
            replanned: false,
        })
    }
}
