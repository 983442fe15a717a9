//! Campaigns split over machines: `--shard I/N` and the checks `grop merge` makes.
//!
//! Shard `I` of `N` (0-based, `0 <= I < N`, as Slurm's `SLURM_ARRAY_TASK_ID` and Kubernetes'
//! `JOB_COMPLETION_INDEX` count) takes the tasks at positions `k` of the job's task list with
//! `k mod N == I`. The share is fixed by `I`, `N` and the task list alone: no shard looks at
//! another, and a shard rerun takes the same tasks.
//!
//! Each shard writes its results into its own folder `shard-III-of-NNN` together with a
//! [`ShardManifest`] (`shard.json`): the job, the seed, the program's version and commit, the
//! whole configuration and the task ids. [`check_set`] refuses a set of shards with one missing,
//! one twice, or one from another campaign (other seed, commit, version or configuration), naming
//! the folder.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// The manifest's file name inside a shard folder.
pub const MANIFEST_FILE: &str = "shard.json";
/// `format` of the manifests this version writes.
pub const MANIFEST_FORMAT: &str = "grop-shard-1";

/// Shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Shard {
    /// 0-based index, below `count`.
    pub index: usize,
    /// Shards in the campaign (at least 1).
    pub count: usize,
}

/// A `--shard` value that is not `I/N` with `0 <= I < N`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("--shard {given:?}: {reason} (expected I/N with 0 <= I < N, e.g. 0/4)")]
pub struct ShardParseError {
    /// The value given.
    pub given: String,
    /// What is wrong with it.
    pub reason: &'static str,
}

impl FromStr for Shard {
    type Err = ShardParseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |reason| ShardParseError {
            given: s.to_owned(),
            reason,
        };
        let (i, n) = s.trim().split_once('/').ok_or_else(|| err("no '/'"))?;
        let index: usize = i.trim().parse().map_err(|_| err("I is not a number"))?;
        let count: usize = n.trim().parse().map_err(|_| err("N is not a number"))?;
        if count == 0 {
            return Err(err("N must be at least 1"));
        }
        if index >= count {
            return Err(err("I must be below N"));
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// The whole campaign as one shard.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Whether position `k` of the task list belongs to this shard (`k mod N == I`).
    pub fn contains(self, k: usize) -> bool {
        k % self.count == self.index
    }

    /// This shard's positions among `n` tasks, in order.
    pub fn positions(self, n: usize) -> Vec<usize> {
        (self.index..n).step_by(self.count).collect()
    }

    /// The shard's folder name: `shard-III-of-NNN`.
    pub fn folder_name(self) -> String {
        format!("shard-{:03}-of-{:03}", self.index, self.count)
    }
}

/// What every shard folder records about the run that wrote it (`shard.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardManifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// The job: `eval`, `hil`, `soak` or `datagen`.
    pub job: String,
    /// Which shard.
    pub shard: Shard,
    /// The campaign's seed.
    pub seed: u64,
    /// The program's version (Cargo package version).
    pub version: String,
    /// `git` commit of the source tree the program ran from (`-dirty` with local changes),
    /// `unknown` where there is no git checkout.
    pub commit: String,
    /// SHA-256 of the running executable (information: builds differ by machine).
    pub binary_sha256: String,
    /// The whole configuration: the command's options (without the shard, the output folder and
    /// the options that change speed only) and a digest of each input file.
    pub config: serde_json::Value,
    /// Tasks in the whole campaign (length of the task list the shards split).
    pub total_tasks: usize,
    /// Ids of the tasks this shard ran, in order.
    pub task_ids: Vec<usize>,
    /// Wall-clock seconds the shard took (information).
    pub wall_s: f64,
}

/// Why a set of shard folders cannot be merged.
#[derive(Debug, thiserror::Error)]
pub enum ShardSetError {
    /// A folder could not be read or holds no readable manifest.
    #[error("shard folder {folder}: {reason}")]
    Unreadable {
        /// The folder.
        folder: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// No folders were given.
    #[error("no shard folders given")]
    Empty,
    /// A shard of another campaign.
    #[error(
        "shard folder {folder} is foreign: its {field} is {theirs} but {first}'s is {ours}; \
         refusing to merge shards of different campaigns"
    )]
    Foreign {
        /// The folder.
        folder: PathBuf,
        /// The folder the others are compared with.
        first: PathBuf,
        /// The field that differs.
        field: String,
        /// Its value in `folder`.
        theirs: String,
        /// Its value in `first`.
        ours: String,
    },
    /// Two folders hold the same shard.
    #[error("shard {shard} is there twice: {a} and {b}")]
    Duplicate {
        /// The shard.
        shard: Shard,
        /// One folder.
        a: PathBuf,
        /// The other.
        b: PathBuf,
    },
    /// A shard is missing.
    #[error("shard {shard} ({}) is missing among the {given} folders given", shard.folder_name())]
    Missing {
        /// The shard.
        shard: Shard,
        /// Folders given.
        given: usize,
    },
    /// A shard's task ids are not its share of the task list.
    #[error("shard folder {folder} ({shard}): {reason}")]
    WrongTasks {
        /// The folder.
        folder: PathBuf,
        /// Its shard.
        shard: Shard,
        /// What is wrong.
        reason: String,
    },
}

/// Reads `folder/shard.json`.
pub fn read_manifest(folder: &Path) -> Result<ShardManifest, ShardSetError> {
    let path = folder.join(MANIFEST_FILE);
    let unreadable = |reason: String| ShardSetError::Unreadable {
        folder: folder.to_path_buf(),
        reason,
    };
    let text = std::fs::read_to_string(&path)
        .map_err(|e| unreadable(format!("{}: {e} (not a shard folder?)", path.display())))?;
    let m: ShardManifest =
        serde_json::from_str(&text).map_err(|e| unreadable(format!("{}: {e}", path.display())))?;
    if m.format != MANIFEST_FORMAT {
        return Err(unreadable(format!(
            "manifest format {:?}, this program reads {MANIFEST_FORMAT:?}",
            m.format
        )));
    }
    if m.shard.count == 0 || m.shard.index >= m.shard.count {
        return Err(unreadable(format!(
            "shard {} is not I/N with I < N",
            m.shard
        )));
    }
    Ok(m)
}

/// The shard folders named by `paths`: each path is a shard folder (it holds `shard.json`) or a
/// folder whose `shard-*` subfolders are shard folders. Sorted by path.
pub fn expand_folders(paths: &[PathBuf]) -> Result<Vec<PathBuf>, ShardSetError> {
    let mut out = Vec::new();
    for p in paths {
        if p.join(MANIFEST_FILE).is_file() {
            out.push(p.clone());
            continue;
        }
        let entries = std::fs::read_dir(p).map_err(|e| ShardSetError::Unreadable {
            folder: p.clone(),
            reason: e.to_string(),
        })?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|q| {
                q.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("shard-"))
                    && q.is_dir()
            })
            .collect();
        if found.is_empty() {
            return Err(ShardSetError::Unreadable {
                folder: p.clone(),
                reason: format!(
                    "neither a shard folder ({MANIFEST_FILE}) nor a folder of shard-* folders"
                ),
            });
        }
        found.sort();
        out.append(&mut found);
    }
    Ok(out)
}

/// Reads the manifests of `folders` and checks that they are exactly the shards `0..N` of one
/// campaign: same job, count, seed, version, commit and configuration, each index once, each
/// with its share of the task list. Returns them ordered by shard index.
pub fn check_set(folders: &[PathBuf]) -> Result<Vec<(PathBuf, ShardManifest)>, ShardSetError> {
    let mut set: Vec<(PathBuf, ShardManifest)> = folders
        .iter()
        .map(|f| read_manifest(f).map(|m| (f.clone(), m)))
        .collect::<Result<_, _>>()?;
    let Some((first_dir, first)) = set.first().cloned() else {
        return Err(ShardSetError::Empty);
    };
    for (dir, m) in &set[1..] {
        let foreign = |field: &str, theirs: String, ours: String| ShardSetError::Foreign {
            folder: dir.clone(),
            first: first_dir.clone(),
            field: field.to_owned(),
            theirs,
            ours,
        };
        if m.job != first.job {
            return Err(foreign("job", m.job.clone(), first.job.clone()));
        }
        if m.shard.count != first.shard.count {
            return Err(foreign(
                "shard count",
                m.shard.count.to_string(),
                first.shard.count.to_string(),
            ));
        }
        if m.seed != first.seed {
            return Err(foreign("seed", m.seed.to_string(), first.seed.to_string()));
        }
        if m.version != first.version {
            return Err(foreign("version", m.version.clone(), first.version.clone()));
        }
        if m.commit != first.commit {
            return Err(foreign("commit", m.commit.clone(), first.commit.clone()));
        }
        if m.total_tasks != first.total_tasks {
            return Err(foreign(
                "task count",
                m.total_tasks.to_string(),
                first.total_tasks.to_string(),
            ));
        }
        if let Some((key, theirs, ours)) = first_difference(&m.config, &first.config) {
            return Err(foreign(&format!("configuration ({key})"), theirs, ours));
        }
    }
    set.sort_by_key(|(_, m)| m.shard.index);
    let mut by_index: BTreeMap<usize, &PathBuf> = BTreeMap::new();
    for (dir, m) in &set {
        if let Some(prev) = by_index.insert(m.shard.index, dir) {
            return Err(ShardSetError::Duplicate {
                shard: m.shard,
                a: prev.clone(),
                b: dir.clone(),
            });
        }
    }
    for index in 0..first.shard.count {
        if !by_index.contains_key(&index) {
            return Err(ShardSetError::Missing {
                shard: Shard {
                    index,
                    count: first.shard.count,
                },
                given: set.len(),
            });
        }
    }
    for (dir, m) in &set {
        let expected = m.shard.positions(m.total_tasks).len();
        if m.task_ids.len() != expected {
            return Err(ShardSetError::WrongTasks {
                folder: dir.clone(),
                shard: m.shard,
                reason: format!(
                    "{} task ids, its share of {} tasks is {expected}",
                    m.task_ids.len(),
                    m.total_tasks
                ),
            });
        }
    }
    Ok(set)
}

/// The first key (dotted path) where two JSON values differ, with both values.
fn first_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
) -> Option<(String, String, String)> {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
            for k in keys {
                match (x.get(k), y.get(k)) {
                    (Some(p), Some(q)) => {
                        if let Some((sub, s, t)) = first_difference(p, q) {
                            let key = if sub.is_empty() {
                                k.clone()
                            } else {
                                format!("{k}.{sub}")
                            };
                            return Some((key, s, t));
                        }
                    }
                    (p, q) => {
                        let show = |v: Option<&Value>| v.map_or("absent".into(), Value::to_string);
                        return Some((k.clone(), show(p), show(q)));
                    }
                }
            }
            None
        }
        _ if a == b => None,
        _ => Some((String::new(), a.to_string(), b.to_string())),
    }
}

/// The git commit of the checkout at `dir` (`-dirty` with local changes), or `unknown`.
pub fn source_commit(dir: &Path) -> String {
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .arg("-C")
            .arg(dir)
            .args(args)
            .stderr(std::process::Stdio::null())
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    match git(&["rev-parse", "HEAD"]) {
        Some(head) if !head.is_empty() => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty());
            if dirty { format!("{head}-dirty") } else { head }
        }
        _ => "unknown".into(),
    }
}

/// SHA-256 (hex) of a file's bytes; `missing: PATH` when it cannot be read.
pub fn file_sha256(path: &Path) -> String {
    use sha2::Digest;
    match std::fs::read(path) {
        Ok(bytes) => {
            let d = sha2::Sha256::digest(&bytes);
            d.iter().map(|b| format!("{b:02x}")).collect()
        }
        Err(_) => format!("missing: {}", path.display()),
    }
}

/// A shard's output folder, written under a temporary name and renamed into place by
/// [`ShardDir::commit`] with its manifest, so a shard killed midway leaves no folder that looks
/// complete. A rerun of the same shard replaces its earlier folder.
#[derive(Debug)]
pub struct ShardDir {
    dest: PathBuf,
    temp: PathBuf,
    committed: bool,
}

impl ShardDir {
    /// `parent/shard-III-of-NNN`, staged as `parent/.shard-III-of-NNN.partial-PID`.
    pub fn create(parent: &Path, shard: Shard) -> std::io::Result<ShardDir> {
        std::fs::create_dir_all(parent)?;
        let name = shard.folder_name();
        let dest = parent.join(&name);
        let temp = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if temp.exists() {
            std::fs::remove_dir_all(&temp)?;
        }
        std::fs::create_dir(&temp)?;
        Ok(ShardDir {
            dest,
            temp,
            committed: false,
        })
    }

    /// Where the shard writes until the commit.
    pub fn path(&self) -> &Path {
        &self.temp
    }

    /// The folder the shard will have after the commit.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Writes the manifest and renames the folder into place (replacing an earlier run of the
    /// same shard; refusing a folder there that is not a shard folder).
    pub fn commit(mut self, manifest: &ShardManifest) -> std::io::Result<PathBuf> {
        let text = serde_json::to_string_pretty(manifest).map_err(std::io::Error::other)?;
        std::fs::write(self.temp.join(MANIFEST_FILE), text + "\n")?;
        if self.dest.exists() {
            let empty = std::fs::read_dir(&self.dest)?.next().is_none();
            if !empty && !self.dest.join(MANIFEST_FILE).is_file() {
                return Err(std::io::Error::other(format!(
                    "{} exists and is not a shard folder; refusing to replace it",
                    self.dest.display()
                )));
            }
            std::fs::remove_dir_all(&self.dest)?;
        }
        std::fs::rename(&self.temp, &self.dest)?;
        self.committed = true;
        Ok(self.dest.clone())
    }
}

impl Drop for ShardDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp);
        }
    }
}

/// The output folder of a merge: written under a temporary name beside `dest` and renamed into
/// place at the end; `dest` must not exist yet or be empty, so nothing already there is ever
/// overwritten, and a failed merge leaves nothing behind.
#[derive(Debug)]
pub struct MergeDir {
    dest: PathBuf,
    temp: PathBuf,
    committed: bool,
}

impl MergeDir {
    /// Checks `dest` and creates the temporary folder.
    pub fn create(dest: &Path) -> std::io::Result<MergeDir> {
        if dest.exists() {
            let empty = dest.is_dir() && std::fs::read_dir(dest)?.next().is_none();
            if !empty {
                return Err(std::io::Error::other(format!(
                    "{} exists and is not empty; merge writes only into a new folder (remove it or choose another --out)",
                    dest.display()
                )));
            }
        }
        let name = dest
            .file_name()
            .ok_or_else(|| std::io::Error::other(format!("{} names no folder", dest.display())))?
            .to_string_lossy()
            .into_owned();
        let parent = dest
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(parent)?;
        let temp = parent.join(format!(".{name}.merging-{}", std::process::id()));
        if temp.exists() {
            std::fs::remove_dir_all(&temp)?;
        }
        std::fs::create_dir(&temp)?;
        Ok(MergeDir {
            dest: dest.to_path_buf(),
            temp,
            committed: false,
        })
    }

    /// Where the merge writes until the commit.
    pub fn path(&self) -> &Path {
        &self.temp
    }

    /// Renames the finished folder to `dest` (which must still be absent or empty).
    pub fn commit(mut self) -> std::io::Result<PathBuf> {
        if self.dest.exists() {
            // rename(2) replaces an empty folder and fails on a non-empty one.
            let empty = std::fs::read_dir(&self.dest)?.next().is_none();
            if !empty {
                return Err(std::io::Error::other(format!(
                    "{} was filled while merging; leaving it alone",
                    self.dest.display()
                )));
            }
        }
        std::fs::rename(&self.temp, &self.dest)?;
        self.committed = true;
        Ok(self.dest.clone())
    }
}

impl Drop for MergeDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_refuses() {
        assert_eq!(
            "2/4".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 4 }
        );
        for bad in ["4/4", "1/0", "x/2", "3", "-1/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn shares_partition_the_tasks() {
        for n in [0usize, 1, 7, 8, 13] {
            for count in 1..6 {
                let mut all: Vec<usize> = (0..count)
                    .flat_map(|index| Shard { index, count }.positions(n))
                    .collect();
                all.sort_unstable();
                assert_eq!(all, (0..n).collect::<Vec<_>>(), "n {n}, count {count}");
            }
        }
        assert_eq!(Shard { index: 1, count: 3 }.positions(8), vec![1, 4, 7]);
    }

    fn manifest(index: usize, count: usize, seed: u64) -> ShardManifest {
        let shard = Shard { index, count };
        ShardManifest {
            format: MANIFEST_FORMAT.into(),
            job: "eval".into(),
            shard,
            seed,
            version: "1".into(),
            commit: "abc".into(),
            binary_sha256: String::new(),
            config: serde_json::json!({"a": 1, "b": {"c": "x"}}),
            total_tasks: 7,
            task_ids: shard.positions(7),
            wall_s: 0.0,
        }
    }

    fn write(dir: &Path, m: &ShardManifest) -> PathBuf {
        let d = ShardDir::create(dir, m.shard).unwrap();
        d.commit(m).unwrap()
    }

    #[test]
    fn refuses_missing_duplicate_and_foreign_shards() {
        let tmp = tempfile::tempdir().unwrap();
        let a = write(tmp.path(), &manifest(0, 3, 5));
        let b = write(tmp.path(), &manifest(1, 3, 5));
        let c = write(tmp.path(), &manifest(2, 3, 5));
        let ok = check_set(&[c.clone(), a.clone(), b.clone()]).unwrap();
        assert_eq!(
            ok.iter().map(|(_, m)| m.shard.index).collect::<Vec<_>>(),
            [0, 1, 2]
        );
        let e = check_set(&[a.clone(), c.clone()]).unwrap_err().to_string();
        assert!(e.contains("shard 1/3") && e.contains("missing"), "{e}");
        let e = check_set(&[a.clone(), b.clone(), b.clone(), c.clone()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("twice"), "{e}");
        let other = tempfile::tempdir().unwrap();
        let f = write(other.path(), &manifest(1, 3, 6));
        let e = check_set(&[a.clone(), f.clone(), c.clone()])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("foreign") && e.contains("seed") && e.contains(&f.display().to_string()),
            "{e}"
        );
        let mut g = manifest(1, 3, 5);
        g.config = serde_json::json!({"a": 1, "b": {"c": "y"}});
        let third = tempfile::tempdir().unwrap();
        let g = write(third.path(), &g);
        let e = check_set(&[a, g, c]).unwrap_err().to_string();
        assert!(e.contains("configuration (b.c)"), "{e}");
        let _ = std::fs::remove_dir_all(tmp.path());
    }

    #[test]
    fn merge_dir_never_overwrites() {
        let tmp = tempfile::tempdir().unwrap();
        let dest = tmp.path().join("merged");
        std::fs::create_dir(&dest).unwrap();
        std::fs::write(dest.join("old.txt"), "old").unwrap();
        assert!(MergeDir::create(&dest).is_err());
        assert_eq!(
            std::fs::read_to_string(dest.join("old.txt")).unwrap(),
            "old"
        );
        let fresh = tmp.path().join("fresh");
        {
            let m = MergeDir::create(&fresh).unwrap();
            std::fs::write(m.path().join("x"), "1").unwrap();
            // Dropped without a commit: nothing appears.
        }
        assert!(!fresh.exists());
        let leftovers: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "only `merged` remains");
        let m = MergeDir::create(&fresh).unwrap();
        std::fs::write(m.path().join("x"), "1").unwrap();
        m.commit().unwrap();
        assert_eq!(std::fs::read_to_string(fresh.join("x")).unwrap(), "1");
    }
}
