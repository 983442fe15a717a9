//! Feasibility heatmaps per task and side: the ground truth (cached on disk, the slow part) and Psi's.

use super::*;

/// Heatmaps for every (scene, target, side): `maps[scene][target][0 near, 1 far]`.
#[derive(Debug, Clone)]
pub struct HeatmapSet {
    /// The heatmaps.
    pub maps: Vec<Vec<[Heatmap; 2]>>,
}

impl HeatmapSet {
    /// The 2n heatmaps of a task in location order.
    pub fn for_task(&self, task: &EvalTask) -> Vec<Heatmap> {
        task.target_ids
            .iter()
            .flat_map(|&t| self.maps[task.scene][t].iter().cloned())
            .collect()
    }
}

fn side_index(side: Side) -> usize {
    usize::from(side == Side::Far)
}

#[derive(Serialize, Deserialize)]
struct GtCache {
    fingerprint: String,
    /// Per (scene, target, side) in order: the 192 candidate-cell values.
    values: Vec<Vec<f32>>,
}

/// Simulated ground truth for every (scene, target, side) over the candidate area
/// (`gt_trials_per_cell` trials per cell, seeded), computed in parallel and cached in `cache`
/// (recomputed when the file was made with other settings).
pub fn ground_truth(
    cfg: &EvalConfig,
    workload: &Workload,
    cache: Option<&Path>,
) -> Result<HeatmapSet, EvalError> {
    let robot_json = serde_json::to_string(&cfg.robot).unwrap_or_default();
    let names: Vec<String> = workload
        .scenes
        .iter()
        .map(|s| format!("{}:{}", s.name, s.targets.len()))
        .collect();
    let fingerprint = format!(
        "v1 seed={} trials={} robot={robot_json} scenes={}",
        cfg.seed,
        cfg.gt_trials_per_cell,
        names.join(",")
    );
    let jobs: Vec<(usize, usize, Side)> = workload
        .scenes
        .iter()
        .enumerate()
        .flat_map(|(s, scene)| {
            (0..scene.targets.len()).flat_map(move |t| Side::BOTH.map(|side| (s, t, side)))
        })
        .collect();
    if let Some(path) = cache.filter(|p| p.exists()) {
        let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        match serde_json::from_str::<GtCache>(&text) {
            Ok(c) if c.fingerprint == fingerprint && c.values.len() == jobs.len() => {
                if c.values.iter().any(|v| v.len() != CANDIDATE_CELLS) {
                    return Err(EvalError::Cache {
                        path: path.to_path_buf(),
                        reason: format!("every entry must hold {CANDIDATE_CELLS} values"),
                    });
                }
                log::info!("ground truth from cache {}", path.display());
                return Ok(assemble(
                    workload,
                    &jobs,
                    c.values.iter().map(|v| candidate_heatmap(v)).collect(),
                ));
            }
            Ok(_) => log::info!(
                "ground-truth cache {} was made with other settings; recomputing",
                path.display()
            ),
            Err(e) => log::warn!(
                "ground-truth cache {} unreadable ({e}); recomputing",
                path.display()
            ),
        }
    }
    log::info!(
        "simulating ground truth: {} heatmaps x {} cells x {} trials",
        jobs.len(),
        CANDIDATE_CELLS,
        cfg.gt_trials_per_cell
    );
    let maps: Vec<Heatmap> = jobs
        .par_iter()
        .map(|&(s, t, side)| {
            let scene = &workload.scenes[s];
            let seed = mix_seed(
                cfg.seed ^ 0x6774,
                (s * 1000 + t) as u64,
                side_index(side) as u64,
            );
            ground_truth_heatmap(
                scene,
                &cfg.robot,
                scene.targets[t].as_array(),
                side,
                cfg.gt_trials_per_cell,
                seed,
            )
        })
        .collect();
    if let Some(path) = cache {
        let values = maps
            .iter()
            .map(|h| candidate_cells().map(|(r, c)| h.get(r, c)).collect())
            .collect();
        let text = serde_json::to_string(&GtCache {
            fingerprint,
            values,
        })
        .map_err(|e| EvalError::Cache {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        std::fs::write(path, text).map_err(|source| EvalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    }
    Ok(assemble(workload, &jobs, maps))
}

fn candidate_heatmap(values: &[f32]) -> Heatmap {
    let mut h = Heatmap::zeros();
    for ((r, c), &v) in candidate_cells().zip(values) {
        h.set(r, c, v);
    }
    h
}

fn assemble(workload: &Workload, jobs: &[(usize, usize, Side)], maps: Vec<Heatmap>) -> HeatmapSet {
    let mut out: Vec<Vec<[Heatmap; 2]>> = workload
        .scenes
        .iter()
        .map(|s| vec![[Heatmap::zeros(), Heatmap::zeros()]; s.targets.len()])
        .collect();
    for (&(s, t, side), h) in jobs.iter().zip(maps) {
        out[s][t][side_index(side)] = h;
    }
    HeatmapSet { maps: out }
}

/// `Psi` for every (scene, target, side) from a feasibility evaluator, in batches of 6 crops.
pub fn evaluate_heatmaps(
    workload: &Workload,
    evaluator: &mut dyn FeasibilityEvaluator,
) -> Result<HeatmapSet, EvalError> {
    let robot = RobotConfig::default();
    let mut maps = Vec::with_capacity(workload.scenes.len());
    for scene in &workload.scenes {
        let mut per_scene = Vec::with_capacity(scene.targets.len());
        for chunk in scene.targets.chunks(3) {
            let crops: Vec<[u8; 2048]> = chunk
                .iter()
                .flat_map(|t| Side::BOTH.map(|side| render_crop(scene, t.x_m, side)))
                .collect();
            let targets: Vec<[f64; 3]> = chunk.iter().map(|t| t.as_array()).collect();
            let mut out = vec![Heatmap::zeros(); crops.len()];
            evaluate_crops(scene, &robot, &targets, &crops, evaluator, &mut out)?;
            for pair in out.chunks(2) {
                per_scene.push([pair[0].clone(), pair[1].clone()]);
            }
        }
        maps.push(per_scene);
    }
    Ok(HeatmapSet { maps })
}
