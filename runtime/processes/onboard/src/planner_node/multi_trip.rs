//! Whole table settings: more objects than the tray holds or the single-trip planner takes,
//! planned as trips ([`MultiTripPlanner`]), objects on board delivered first.

use super::*;

impl PlannerNode {
    /// Several trips over `objects` (those on board first, then those at the station, as
    /// `plan_and_publish` orders them; `targets` and the heatmap buffers in the same order): the
    /// objects on board are delivered first with the single-trip planner (station on the pose,
    /// no station visit), then the multi-trip planner ([`MultiTripPlanner`], a tray of
    /// `carry_capacity`) plans the objects at the station from where that leaves the robot.
    /// Per trip: navigate to the station, one load step with the trip's objects, navigate +
    /// unload per object. Returns the steps, (F, C, U) of the steps (C = the sum of their legs,
    /// U = R F - C) and `Fea^t` per location in `objects` order.
    #[allow(clippy::type_complexity)]
    #[allow(
        clippy::too_many_lines,
        reason = "one multi-trip request planned in order: frame, problem, trips, checks, message"
    )]
    pub(super) fn plan_trips(
        &mut self,
        objects: &[usize],
        targets: &[[f64; 3]],
        on_board: u64,
        pose_xy: (f64, f64),
        seed: u64,
        capacity: usize,
    ) -> Result<(Vec<TaskStep>, (f64, f64, f64), Vec<f64>), RequestError> {
        let n_board = objects
            .iter()
            .take_while(|&&o| on_board & (1 << o) != 0)
            .count();
        let mut travel = GridTravelTime::new(&self.grid, self.robot.speed_mps);
        let no_path_s = self.planner.config.no_path_cost_s;
        let mut steps = Vec::new();
        let mut feasibility_of = Vec::with_capacity(2 * objects.len());
        let mut at = pose_xy;
        let mut capacity = capacity;
        if n_board > 0 {
            let mut problem = TaskProblem::from_heatmaps(
                &self.scene,
                &self.robot,
                &targets[..n_board],
                &self.heat_buffers[..2 * n_board],
            );
            problem.start_xy = pose_xy;
            problem.station_xy = pose_xy;
            let decision = self.planner.plan(&problem, &mut travel, seed)?;
            steps = self.steps_of(
                &decision,
                &objects[..n_board],
                &targets[..n_board],
                0,
                pose_xy,
                &mut travel,
            );
            feasibility_of.extend(decision.locations.iter().map(|l| l.feasibility));
            if let Some(last) = decision.plan.unloads.last() {
                at = decision.goal_of(last).xy;
            }
            // An object on board that the decision leaves out (not worth its cost) keeps its
            // slot for the trips after.
            let kept = n_board.saturating_sub(decision.plan.unloads.len());
            capacity = capacity.saturating_sub(kept);
        }
        let rest = if capacity == 0 {
            log::warn!(
                "the tray stays full of objects the plan does not unload: {} objects at the \
                 station are not planned",
                objects.len() - n_board
            );
            &objects[..0]
        } else {
            &objects[n_board..]
        };
        if !rest.is_empty() {
            let mut problem = TaskProblem::from_heatmaps(
                &self.scene,
                &self.robot,
                &targets[n_board..],
                &self.heat_buffers[2 * n_board..2 * objects.len()],
            );
            problem.start_xy = at;
            let trips = MultiTripPlanner::new(self.planner.kind, self.planner.config, capacity)
                .plan(&problem, &mut travel, seed)?;
            log::debug!(
                "{} trips over {} objects: U {:.2}, F {:.3}, C {:.1} s, bound {:?}",
                trips.plan.trips.len(),
                rest.len(),
                trips.utility,
                trips.feasibility,
                trips.cost_s,
                trips.search.map(|r| r.upper_bound)
            );
            feasibility_of.extend(trips.locations.iter().map(|l| l.feasibility));
            let station = (
                self.scene.loading_station.x_m,
                self.scene.loading_station.y_m,
            );
            let mut leg = |from: (f64, f64), to: (f64, f64)| {
                travel.travel_time_s(from, to).unwrap_or(no_path_s)
            };
            for trip in &trips.plan.trips {
                let mask = trip
                    .load_order
                    .iter()
                    .fold(0u64, |m, &o| m | (1u64 << rest[o]));
                steps.push(TaskStep::navigate(
                    station.0,
                    station.1,
                    self.station_yaw_rad(),
                    leg(at, station),
                ));
                steps.push(TaskStep::load(mask, station.0, station.1));
                at = station;
                for u in &trip.unloads {
                    let goal = trips.goal_of(u);
                    let mut nav =
                        TaskStep::navigate(goal.xy.0, goal.xy.1, goal.yaw_rad, leg(at, goal.xy));
                    nav.side = i32::from(u.side.sign());
                    steps.push(nav);
                    steps.push(TaskStep::unload(
                        rest[u.object] as u32,
                        table_side(u.side),
                        targets[n_board + u.object],
                        [goal.xy.0, goal.xy.1, goal.yaw_rad],
                        trips.locations[location_index(u.object, u.side)].feasibility,
                    ));
                    at = goal.xy;
                }
            }
        }
        let feasibility: f64 = steps
            .iter()
            .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
            .map(|s| s.feasibility)
            .sum();
        let cost_s: f64 = steps.iter().map(|s| s.travel_cost_s).sum();
        let utility = self.planner.config.success_bonus_r * feasibility - cost_s;
        Ok((steps, (feasibility, cost_s, utility), feasibility_of))
    }
}
