//! The workload: the evaluation scenes' tasks, as the planners see them.

use super::*;

/// One evaluation task: 3 targets in one scene.
#[derive(Debug, Clone)]
pub struct EvalTask {
    /// Task id (0..420).
    pub id: usize,
    /// Index of the scene.
    pub scene: usize,
    /// Chairs in the scene.
    pub n_chairs: usize,
    /// Indices of the targets in the scene's target list.
    pub target_ids: Vec<usize>,
}

/// The scenes, their occupancy grids and the tasks.
pub struct Workload {
    /// The evaluation scenes.
    pub scenes: Vec<Scene>,
    /// One grid per scene.
    pub grids: Vec<OccupancyGrid>,
    /// All tasks, scene by scene.
    pub tasks: Vec<EvalTask>,
}

impl Workload {
    /// The paper's scenes (10 x 15, 20, 25 chairs) with `tasks_per_scene * objects_per_task`
    /// targets each; task k of a scene uses targets `k*3 .. k*3+3`.
    pub fn build(cfg: &EvalConfig) -> Self {
        let n_targets = cfg.tasks_per_scene * cfg.objects_per_task;
        let mut scenes: Vec<Scene> =
            if cfg.chair_counts == [15, 20, 25] && cfg.scenes_per_chair_count == 10 {
                evaluation_suite(cfg.seed, n_targets)
            } else {
                cfg.chair_counts
                    .iter()
                    .flat_map(|&c| {
                        (0..cfg.scenes_per_chair_count as u64).map(move |i| {
                            world::generate::evaluation_scene(
                                mix_seed(cfg.seed, c as u64, i),
                                c,
                                n_targets,
                            )
                        })
                    })
                    .collect()
            };
        scenes
            .iter_mut()
            .for_each(|s| s.targets.truncate(n_targets));
        let grids = scenes
            .par_iter()
            .map(|s| OccupancyGrid::from_scene(s, &cfg.robot))
            .collect();
        let mut tasks = Vec::new();
        for (si, scene) in scenes.iter().enumerate() {
            for k in 0..cfg.tasks_per_scene {
                tasks.push(EvalTask {
                    id: tasks.len(),
                    scene: si,
                    n_chairs: scene.chairs.len(),
                    target_ids: (k * cfg.objects_per_task..(k + 1) * cfg.objects_per_task)
                        .collect(),
                });
            }
        }
        Self {
            scenes,
            grids,
            tasks,
        }
    }

    /// The (x, y, z) of a task's targets.
    pub fn targets(&self, task: &EvalTask) -> Vec<[f64; 3]> {
        task.target_ids
            .iter()
            .map(|&t| self.scenes[task.scene].targets[t].as_array())
            .collect()
    }
}
