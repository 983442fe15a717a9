//! The planners' settings: the method, its goal and search options, GROP+'s levers, and the
//! navigation goals they choose. Apart from the planners so that they depend on it, not on each
//! other (`methods` uses `grop_plus`'s functions; both read these settings).

use grop_select::FeasibilityAggregation;

/// The planning methods compared in the paper.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MethodKind {
    /// GROP+: GROP with the levers of [`crate::grop_plus`] (retries, best-of-n draws, goal
    /// margin, R following speed); the planner's default. Not the paper's algorithm.
    GropPlus,
    /// GROP (ours, Algorithm 1).
    Grop,
    /// Satisficing: any valid plan, no costs, equal feasibility.
    Satisficing,
    /// PETLON: cost-optimal task plan, no feasibility.
    Petlon,
    /// DVH: feasibility-optimal, no costs.
    Dvh,
    /// FCN-Planning: GROP's utility with uniform goal choice.
    FcnPlanning,
}

impl MethodKind {
    /// All methods, GROP+ and GROP first.
    pub const ALL: [MethodKind; 6] = [
        MethodKind::GropPlus,
        MethodKind::Grop,
        MethodKind::Satisficing,
        MethodKind::Petlon,
        MethodKind::Dvh,
        MethodKind::FcnPlanning,
    ];

    /// Name used in tables and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            MethodKind::GropPlus => "GROP+",
            MethodKind::Grop => "GROP",
            MethodKind::Satisficing => "Satisficing",
            MethodKind::Petlon => "PETLON",
            MethodKind::Dvh => "DVH",
            MethodKind::FcnPlanning => "FCN-Planning",
        }
    }

    /// Parses a name case-insensitively (`grop+` or `grop-plus`, `grop`, `satisficing`, `petlon`,
    /// `dvh`, `fcn-planning`).
    pub fn parse(name: &str) -> Option<MethodKind> {
        let n = name.trim().to_ascii_lowercase().replace('_', "-");
        if n == "grop-plus" || n == "gropplus" {
            return Some(MethodKind::GropPlus);
        }
        MethodKind::ALL
            .into_iter()
            .find(|m| m.name().to_ascii_lowercase() == n)
    }

    /// Does the method choose goals from the heatmap with `Smp`?
    pub fn uses_smp_goals(self) -> bool {
        matches!(self, MethodKind::Grop | MethodKind::GropPlus)
    }
}

/// How the baselines choose navigation goals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BaselineGoals {
    /// The paper: uniform among the obstacle-free cells of the candidate area.
    #[default]
    Paper,
    /// The authors' code: uniform among cells with a nonzero heatmap value; Satisficing uniform
    /// in a fixed, scene-independent region (the middle 12 x 4 cells of the candidate area).
    AuthorsCode,
}

/// How the utility-based methods search the plan space.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SearchMode {
    /// Enumerate when there are at most 4 objects (9216 plans), else the exact optimiser.
    #[default]
    Auto,
    /// Enumerate every satisficing plan (at most [`crate::task::MAX_ENUMERATED_OBJECTS`] objects); the
    /// decision lists every plan's F, C and U.
    Enumerate,
    /// The exact optimiser ([`crate::task::optimise`]).
    Exact,
}

/// Planner settings. `Default` is the paper's GROP on the paper's robot, except that GROP draws its goals
/// over obstacle-free cells only ([`PlannerConfig::free_goals_only`]; `false` is the paper).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerConfig {
    /// Success bonus `R` of eq. 1 (paper: 40).
    pub success_bonus_r: f64,
    /// Sum (paper) or product of the pairs' feasibilities.
    pub aggregation: FeasibilityAggregation,
    /// Number of `Smp` draws per (target, side), keeping the best (paper: 1).
    pub goal_draws: usize,
    /// How the utility methods search.
    pub search: SearchMode,
    /// Cost of a leg the navigation planner finds no path for (s); the evaluation charges a
    /// failed navigation 60 s.
    pub no_path_cost_s: f64,
    /// Cruise speed (m/s) used for PETLON's optimistic straight-line costs; must match the
    /// travel-time oracle's speed.
    pub speed_mps: f64,
    /// Baselines' goal choice.
    pub baseline_goals: BaselineGoals,
    /// GROP and FCN-Planning: cost legs lazily, PETLON-style (optimistic straight-line costs,
    /// refined by the motion planner only for the current best plan until it is stable). Same
    /// argmax as costing every leg (utilities under optimistic costs are upper bounds), far fewer
    /// motion-planner calls for many objects; the decision's candidate list then holds optimistic
    /// costs for plans that were never best. Off by default (the paper costs every leg).
    pub lazy_costs: bool,
    /// GROP: read the heatmap only over the obstacle-free candidate cells (where the base,
    /// commanded there facing the table, fits the map). Smp then never sends the base to a goal
    /// it would collide at, and `Fea^t` (eq. 4, the expected success of an Smp draw) is computed
    /// over the same cells, so it predicts the goals actually drawn. On by default: the paper
    /// draws from the whole heatmap (`false`), which sends the base into known furniture whenever
    /// the draw lands on a cell the noise might still rescue (docs/planner.md, "Smp over free
    /// cells").
    pub free_goals_only: bool,
    /// GROP+'s levers (read by [`MethodKind::GropPlus`] only; the other methods ignore them).
    pub plus: GropPlusConfig,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        Self {
            success_bonus_r: 40.0,
            aggregation: FeasibilityAggregation::Sum,
            goal_draws: 1,
            search: SearchMode::Auto,
            no_path_cost_s: 60.0,
            speed_mps: 0.4,
            baseline_goals: BaselineGoals::Paper,
            lazy_costs: false,
            free_goals_only: true,
            plus: GropPlusConfig::DEFAULT,
        }
    }
}

impl PlannerConfig {
    /// The defaults with the robot file's `R` and speed.
    pub fn for_robot(robot: &world::RobotConfig) -> Self {
        Self {
            success_bonus_r: robot.success_bonus_r,
            speed_mps: robot.speed_mps,
            ..Self::default()
        }
    }
}

/// How a navigation goal was chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GoalSource {
    /// `Smp` from the heatmap (best of `goal_draws`).
    Smp,
    /// Uniform among obstacle-free cells.
    UniformFree,
    /// Uniform among cells with a nonzero heatmap value (authors' code variant).
    UniformNonzero,
    /// Uniform in the fixed region (authors' Satisficing).
    FixedRegion,
    /// Uniform among all candidate cells: nothing better existed (all-zero heatmap, no free cell).
    UniformAny,
    /// GROP+'s retry after a failed unload ([`crate::grop_plus::retry_goal`]).
    Retry,
}

/// A navigation goal: where the base is commanded to stand for one (target, side).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavGoal {
    /// Location index (`2 * object + side`).
    pub location: usize,
    /// Index into the location's candidate cells.
    pub cell: usize,
    /// Crop row and column of the cell.
    pub row_col: (usize, usize),
    /// World position (m).
    pub xy: (f64, f64),
    /// Base yaw facing the table (rad).
    pub yaw_rad: f64,
    /// The heatmap value `h[x]` at the goal.
    pub heat_value: f32,
    /// How it was chosen.
    pub source: GoalSource,
}

/// Most retries a configuration may ask for.
pub const MAX_RETRIES: usize = 8;

/// GROP+'s levers. [`GropPlusConfig::DEFAULT`] is the combination chosen by measurement
/// (docs/experiments.md, "GROP+").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GropPlusConfig {
    /// Retries after a failed unload (0: none, as GROP).
    pub max_retries: usize,
    /// `Smp` draws per (target, side), keeping the best; `None`: GROP's
    /// ([`PlannerConfig::goal_draws`]).
    pub goal_draws: Option<usize>,
    /// Goals only on cells at least this far (m) from every candidate cell where the base would
    /// collide (0: off). When no cell of a location clears the margin with a nonzero heatmap
    /// value, the location falls back to GROP's cells.
    pub goal_margin_m: f64,
    /// `R` scaled by [`R_REFERENCE_SPEED_MPS`] / speed.
    pub r_follows_speed: bool,
}

impl GropPlusConfig {
    /// Every lever off: GROP.
    pub const OFF: GropPlusConfig = GropPlusConfig {
        max_retries: 0,
        goal_draws: None,
        goal_margin_m: 0.0,
        r_follows_speed: false,
    };

    /// The default GROP+, chosen by measurement on the 4,200-task set (docs/experiments.md,
    /// "GROP+"): one retry, best of 20 draws, goals 0.2 m (two noise sigmas) clear of collision
    /// cells. A second retry places more (hard third 0.94 vs 0.91) but costs more time than GROP
    /// on the hard third; fewer draws or a smaller margin cost time too. R following speed stays
    /// off: it changes nothing at 0.4 m/s and only moves completion between the slow and the
    /// fast end of the sweep (+0.015 at 0.2 m/s, -0.018 at 0.8 m/s).
    pub const DEFAULT: GropPlusConfig = GropPlusConfig {
        max_retries: 1,
        goal_draws: Some(20),
        goal_margin_m: 0.2,
        r_follows_speed: false,
    };

    /// Checks the values a user can set.
    pub fn check(&self) -> Result<(), &'static str> {
        if self.max_retries > MAX_RETRIES {
            return Err("GROP+ retries must be at most 8");
        }
        if self.goal_draws.is_some_and(|n| n == 0 || n > 64) {
            return Err("GROP+ goal draws must be in 1..=64");
        }
        if !(self.goal_margin_m.is_finite() && (0.0..=1.0).contains(&self.goal_margin_m)) {
            return Err("GROP+ goal margin must be in 0..=1 m");
        }
        Ok(())
    }

    /// The planner settings GROP+ plans with: GROP's with the goal draws and `R` of the levers.
    pub fn effective(&self, base: &PlannerConfig) -> PlannerConfig {
        PlannerConfig {
            goal_draws: self.goal_draws.unwrap_or(base.goal_draws),
            success_bonus_r: effective_r(base, self.r_follows_speed),
            ..*base
        }
    }
}

/// Speed at which `R` keeps its configured value when [`GropPlusConfig::r_follows_speed`] is on:
/// the authors' 0.4 m/s, where R = 40 was chosen.
pub const R_REFERENCE_SPEED_MPS: f64 = 0.4;

/// `R` of eq. 1 at the configured speed: as configured, or scaled by
/// [`R_REFERENCE_SPEED_MPS`] / speed when it follows speed.
pub fn effective_r(config: &PlannerConfig, follows_speed: bool) -> f64 {
    if follows_speed {
        config.success_bonus_r * R_REFERENCE_SPEED_MPS / config.speed_mps
    } else {
        config.success_bonus_r
    }
}
