//! Records on disk: CSV, and the exact tab-separated form shards are merged from.

use super::*;

/// Writes the records as CSV.
pub fn write_csv(path: &Path, records: &[TaskRecord]) -> Result<(), EvalError> {
    use std::fmt::Write;
    let mut s = String::from(
        "task,scene,n_chairs,speed_mps,method,difficulty,servable_area_m2,objects,placed,time_s,distance_m,predicted_f,predicted_cost_s,motion_planner_calls,retries,steps\n",
    );
    for r in records {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.4},{},{},{:.2},{:.2},{:.4},{:.2},{},{},{}",
            r.task,
            r.scene,
            r.n_chairs,
            r.speed_mps,
            r.method,
            r.difficulty.name(),
            r.servable_area_m2,
            r.objects,
            r.placed,
            r.time_s,
            r.distance_m,
            r.predicted_f,
            r.predicted_cost_s,
            r.motion_planner_calls,
            r.retries,
            r.steps
        );
    }
    write_file(path, &s)
}

/// Header of [`write_records_exact`]'s files.
const EXACT_HEADER: &str = "grop-eval-records-1\ttask\tscene\tn_chairs\tspeed_mps\tmethod\tdifficulty\tservable_area_m2\tobjects\tplaced\ttime_s\tdistance_m\tpredicted_f\tpredicted_cost_s\tmotion_planner_calls\tretries\tsteps";

/// Writes records exactly (a shard's results): tab-separated, every number in Rust's shortest
/// round-trip form, so [`read_records_exact`] gives back the very same values.
pub fn write_records_exact(path: &Path, records: &[TaskRecord]) -> Result<(), EvalError> {
    use std::fmt::Write;
    let mut s = String::from(EXACT_HEADER);
    s.push('\n');
    for r in records {
        let _ = writeln!(
            s,
            "\t{}\t{}\t{}\t{:?}\t{}\t{}\t{:?}\t{}\t{}\t{:?}\t{:?}\t{:?}\t{:?}\t{}\t{}\t{}",
            r.task,
            r.scene,
            r.n_chairs,
            r.speed_mps,
            r.method,
            r.difficulty.name(),
            r.servable_area_m2,
            r.objects,
            r.placed,
            r.time_s,
            r.distance_m,
            r.predicted_f,
            r.predicted_cost_s,
            r.motion_planner_calls,
            r.retries,
            r.steps
        );
    }
    write_file(path, &s)
}

/// Reads what [`write_records_exact`] wrote.
pub fn read_records_exact(path: &Path) -> Result<Vec<TaskRecord>, EvalError> {
    let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |line: usize, reason: String| EvalError::Records {
        path: path.to_path_buf(),
        reason: format!("line {line}: {reason}"),
    };
    let mut lines = text.lines();
    if lines.next() != Some(EXACT_HEADER) {
        return Err(bad(1, "not a grop eval records file (header)".into()));
    }
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        let n = i + 2;
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() != 17 || !f[0].is_empty() {
            return Err(bad(n, format!("{} fields, expected 17", f.len())));
        }
        fn num<T: std::str::FromStr>(s: &str, what: &str) -> Result<T, String> {
            s.parse()
                .map_err(|_| format!("{what} {s:?} is not a number"))
        }
        let rec = (|| -> Result<TaskRecord, String> {
            let method = MethodKind::parse(f[5])
                .ok_or_else(|| format!("unknown method {:?}", f[5]))?
                .name();
            let difficulty = Difficulty::ALL
                .into_iter()
                .find(|d| d.name() == f[6])
                .ok_or_else(|| format!("unknown difficulty {:?}", f[6]))?;
            Ok(TaskRecord {
                task: num(f[1], "task")?,
                scene: num(f[2], "scene")?,
                n_chairs: num(f[3], "n_chairs")?,
                speed_mps: num(f[4], "speed_mps")?,
                method,
                difficulty,
                servable_area_m2: num(f[7], "servable_area_m2")?,
                objects: num(f[8], "objects")?,
                placed: num(f[9], "placed")?,
                time_s: num(f[10], "time_s")?,
                distance_m: num(f[11], "distance_m")?,
                predicted_f: num(f[12], "predicted_f")?,
                predicted_cost_s: num(f[13], "predicted_cost_s")?,
                motion_planner_calls: num(f[14], "motion_planner_calls")?,
                retries: num(f[15], "retries")?,
                steps: f[16].to_owned(),
            })
        })()
        .map_err(|e| bad(n, e))?;
        out.push(rec);
    }
    Ok(out)
}

/// Writes a text file, creating its folder.
pub fn write_file(path: &Path, text: &str) -> Result<(), EvalError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    std::fs::write(path, text).map_err(|source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    })
}
