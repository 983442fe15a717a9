//! The deployment file: everything that differs between the robot, a HIL run and a test, read by
//! both onboard binaries (`grop-planner`, `grop-executive`). Static structure, no environment
//! switches: one TOML file, unknown keys rejected, every value validated on load, errors naming
//! the file and the field. Relative paths resolve against the file's folder.
//!
//! ```toml
//! namespace = "robot"          # iceoryx2 namespace every service name starts with
//! map = "scene.toml"           # world::Scene: tables, chairs, targets (static knowledge)
//! robot = "robot.toml"         # world::RobotConfig (optional: the paper's robot)
//! model = "psi-fcn.onnx"       # Psi, the FCN (ONNX)
//! can = "socketcan:can0"       # or "vcan:<bus>" (userspace virtual bus on iceoryx2)
//! clock = "wall"               # or "sim:<name>" (lock-step HIL clock); default "wall"
//! seed = 42                    # Smp draws and tie-breaks; default 0
//! lidar = "udp:0.0.0.0:2368"   # the VLP-16's data port, or "none" (no collision monitor:
//!                              # refused on a real CAN bus); absent: "none" on vcan
//! lidar_sensor = "192.168.1.201"  # optional: the sensor's address; datagrams from any
//!                              # other sender are dropped (docs/security.md)
//!
//! [arm]                        # UR5e controller
//! host = "192.168.1.10"
//! rtde_port = 30004            # defaults: the UR ports
//! dashboard_port = 29999
//! script_port = 30002
//! gripper_port = 63352
//!
//! [inputs]                     # optional: the iceoryx2 node allowed to publish each command
//! plans = "grop-planner"       # input of the executive (docs/security.md); these are the
//! planner_heartbeats = "grop-planner"  # defaults; the HIL world publishes the fixes as
//! fixes = "grop-localiser"     # "world"
//! operator = "grop-enable"     # the operator's enable (`grop enable`; the HIL world: "world")
//!
//! [planner]                    # optional section
//! method = "grop"              # grop | petlon | dvh | fcn-planning | satisficing
//! paper_smp = false            # true: Smp over the whole heatmap, as the paper
//! retry = "none"               # none (the paper: a failed object is dropped) | replan | grop-plus
//! ```

use std::path::{Path, PathBuf};

use planner::methods::MethodKind;

pub use crate::executive::inputs::InputSources;
use serde::Deserialize;

/// Why a deployment file could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeploymentError {
    /// The file could not be read.
    #[error("reading deployment file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not have the deployment's shape (unknown or missing
    /// key, wrong type; toml's message names the key and line).
    #[error("deployment file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// toml's description.
        message: String,
    },
    /// A value is out of range.
    #[error("deployment file {path}: `{field}` {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The key, dotted (`arm.rtde_port`).
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
}

/// Most bytes a deployment file may have (a real one is about 2 kB).
pub const MAX_DEPLOYMENT_FILE_BYTES: u64 = 1 << 20;

/// Where the base's CAN frames go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CanSpec {
    /// The userspace virtual bus on iceoryx2 (`vcan:<bus>`), for HIL on machines without CAN.
    Virtual {
        /// Bus name.
        bus: String,
    },
    /// A SocketCAN interface (`socketcan:<ifname>`, e.g. `can0` or `vcan0`).
    SocketCan {
        /// Interface name.
        ifname: String,
    },
}

impl CanSpec {
    /// Parses `vcan:<bus>` or `socketcan:<ifname>`.
    pub fn parse(spec: &str) -> Result<Self, String> {
        let (kind, name) = spec
            .split_once(':')
            .ok_or_else(|| format!("{spec:?} is not `vcan:<bus>` or `socketcan:<ifname>`"))?;
        let valid = !name.is_empty()
            && name.len() <= 64
            && name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b));
        if !valid {
            return Err(format!(
                "{spec:?}: the name must be 1-64 characters of letters, digits, `-`, `_`, `.`"
            ));
        }
        match kind {
            "vcan" => Ok(Self::Virtual {
                bus: name.to_owned(),
            }),
            "socketcan" => {
                // Linux interface names are at most 15 bytes (IFNAMSIZ - 1).
                if name.len() > 15 {
                    return Err(format!("{spec:?}: interface names are at most 15 bytes"));
                }
                Ok(Self::SocketCan {
                    ifname: name.to_owned(),
                })
            }
            _ => Err(format!(
                "{spec:?} is not `vcan:<bus>` or `socketcan:<ifname>`"
            )),
        }
    }
}

impl std::fmt::Display for CanSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Virtual { bus } => write!(f, "vcan:{bus}"),
            Self::SocketCan { ifname } => write!(f, "socketcan:{ifname}"),
        }
    }
}

/// Where the range sensor's packets arrive.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum LidarSource {
    /// No range sensor: the collision monitor is off (HIL and tests that do not simulate one;
    /// refused with a real CAN bus unless the file says `lidar = "none"` itself).
    #[default]
    None,
    /// A VLP-16's data packets on this UDP address (`host:port`; on the robot
    /// `0.0.0.0:2368`).
    Udp(String),
}

impl LidarSource {
    /// Parses `none` or `udp:<host>:<port>`.
    pub fn parse(spec: &str) -> Result<Self, String> {
        if spec == "none" {
            return Ok(Self::None);
        }
        let addr = spec
            .strip_prefix("udp:")
            .ok_or_else(|| format!("{spec:?} is not `none` or `udp:<host>:<port>`"))?;
        match addr.rsplit_once(':') {
            Some((host, port))
                if !host.is_empty()
                    && !host.contains(char::is_whitespace)
                    && port.parse::<u16>().is_ok_and(|p| p != 0) =>
            {
                Ok(Self::Udp(addr.to_owned()))
            }
            _ => Err(format!(
                "{spec:?}: expected `udp:<host>:<port>` with a port of 1-65535"
            )),
        }
    }
}

impl std::fmt::Display for LidarSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::None => write!(f, "none"),
            Self::Udp(addr) => write!(f, "udp:{addr}"),
        }
    }
}

/// The UR5e controller's address.
#[derive(Clone, Debug, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmAddress {
    /// Host name or IP address.
    pub host: String,
    /// RTDE (default 30004).
    #[serde(default = "default_rtde_port")]
    pub rtde_port: u16,
    /// Dashboard server (default 29999).
    #[serde(default = "default_dashboard_port")]
    pub dashboard_port: u16,
    /// URScript, secondary interface (default 30002).
    #[serde(default = "default_script_port")]
    pub script_port: u16,
    /// Robotiq gripper URCap socket (default 63352).
    #[serde(default = "default_gripper_port")]
    pub gripper_port: u16,
}

fn default_rtde_port() -> u16 {
    30004
}
fn default_dashboard_port() -> u16 {
    29999
}
fn default_script_port() -> u16 {
    30002
}
fn default_gripper_port() -> u16 {
    63352
}

impl ArmAddress {
    /// The UR ports on `host`.
    pub fn standard(host: &str) -> Self {
        Self {
            host: host.to_owned(),
            rtde_port: default_rtde_port(),
            dashboard_port: default_dashboard_port(),
            script_port: default_script_port(),
            gripper_port: default_gripper_port(),
        }
    }
}

/// What the planner node does after a failed unload.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RetryPolicy {
    /// The paper: no retry. The failed object is dropped; the rest of the current plan goes on.
    #[default]
    None,
    /// Plan again over what is left from where the robot stands, with a fresh frame.
    Replan,
    /// GROP+'s retry policy (`planner::grop_plus::retry_goal`, the one `grop eval` measures):
    /// drive to the best untried cell of either side of the failed object, from where the robot
    /// stands, and unload again, then go on with the rest of the plan; at most the planner's
    /// `max_retries` retries per object, after which the object is dropped as with `None`.
    #[serde(rename = "grop-plus")]
    GropPlus,
}

/// Which planner the node runs and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannerSettings {
    /// GROP or a baseline.
    pub method: MethodKind,
    /// Smp over the whole heatmap as in the paper (`PlannerConfig::free_goals_only = false`).
    pub paper_smp: bool,
    /// After a failed unload.
    pub retry: RetryPolicy,
}

impl Default for PlannerSettings {
    fn default() -> Self {
        Self {
            method: MethodKind::Grop,
            paper_smp: false,
            retry: RetryPolicy::None,
        }
    }
}

/// A validated deployment. Paths are absolute or relative to the working folder (those of a
/// file were resolved against its folder).
#[derive(Clone, Debug, PartialEq)]
pub struct Deployment {
    /// The file it came from (empty for [`Deployment::local`]).
    pub source: PathBuf,
    /// iceoryx2 namespace.
    pub namespace: String,
    /// Scene file: the map and the task (tables, chairs, targets).
    pub map: PathBuf,
    /// Robot file; `None`: the paper's robot (`RobotConfig::default`).
    pub robot: Option<PathBuf>,
    /// Psi's ONNX file.
    pub model: PathBuf,
    /// The base's CAN bus.
    pub can: CanSpec,
    /// The arm's address.
    pub arm: ArmAddress,
    /// Clock spec for `grop_clock::open`: `wall` or `sim:<name>`.
    pub clock: String,
    /// Planner settings.
    pub planner: PlannerSettings,
    /// Seed of every random choice of the planner.
    pub seed: u64,
    /// The range sensor feeding the collision monitor.
    pub lidar: LidarSource,
    /// The node allowed to publish each command input of the executive.
    pub inputs: InputSources,
    /// The range sensor's address: its packets only are read (`None`: any sender's).
    pub lidar_sensor: Option<std::net::IpAddr>,
}

/// The file's shape.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DeploymentFile {
    namespace: String,
    map: PathBuf,
    #[serde(default)]
    robot: Option<PathBuf>,
    model: PathBuf,
    can: String,
    #[serde(default = "default_clock")]
    clock: String,
    #[serde(default)]
    seed: u64,
    arm: ArmAddress,
    #[serde(default)]
    planner: PlannerFile,
    #[serde(default)]
    lidar: Option<String>,
    #[serde(default)]
    inputs: InputsFile,
    #[serde(default)]
    lidar_sensor: Option<String>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct InputsFile {
    #[serde(default)]
    plans: Option<String>,
    #[serde(default)]
    planner_heartbeats: Option<String>,
    #[serde(default)]
    fixes: Option<String>,
    #[serde(default)]
    operator: Option<String>,
}

fn default_clock() -> String {
    "wall".to_owned()
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PlannerFile {
    #[serde(default)]
    method: Option<String>,
    #[serde(default)]
    paper_smp: bool,
    #[serde(default)]
    retry: RetryPolicy,
}

impl Deployment {
    /// Reads and validates a deployment file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DeploymentError> {
        use std::io::Read;
        let path = path.as_ref();
        let read = |source| DeploymentError::Read {
            path: path.to_owned(),
            source,
        };
        // At most MAX_DEPLOYMENT_FILE_BYTES (+1 to tell that there is more): a bigger file, or
        // a special file that never ends, is refused before it fills the memory.
        let mut text = String::new();
        std::fs::File::open(path)
            .map_err(read)?
            .take(MAX_DEPLOYMENT_FILE_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(read)?;
        if text.len() as u64 > MAX_DEPLOYMENT_FILE_BYTES {
            return Err(DeploymentError::Parse {
                path: path.to_owned(),
                message: format!(
                    "larger than the {MAX_DEPLOYMENT_FILE_BYTES} bytes a deployment file may have"
                ),
            });
        }
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates the text of a deployment file found at `path` (relative paths in it
    /// resolve against `path`'s folder).
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, DeploymentError> {
        let file: DeploymentFile = toml::from_str(text).map_err(|e| DeploymentError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let invalid = |field: &'static str, reason: String| DeploymentError::Invalid {
            path: path.to_owned(),
            field,
            reason,
        };
        let base = path.parent().unwrap_or(Path::new(""));
        let resolve = |p: PathBuf| if p.is_absolute() { p } else { base.join(p) };
        let method = match file.planner.method.as_deref() {
            None => MethodKind::Grop,
            Some(name) => MethodKind::parse(name).ok_or_else(|| {
                invalid(
                    "planner.method",
                    format!("{name:?} is not grop, petlon, dvh, fcn-planning or satisficing"),
                )
            })?,
        };
        let can = CanSpec::parse(&file.can).map_err(|reason| invalid("can", reason))?;
        let lidar = match file.lidar.as_deref() {
            Some(spec) => LidarSource::parse(spec).map_err(|reason| invalid("lidar", reason))?,
            None if matches!(can, CanSpec::SocketCan { .. }) => {
                return Err(invalid(
                    "lidar",
                    "is missing: a base on a real CAN bus drives only with its range sensor \
                     (lidar = \"udp:0.0.0.0:2368\"); say lidar = \"none\" to drive without \
                     the collision monitor"
                        .to_owned(),
                ));
            }
            None => LidarSource::None,
        };
        let defaults = InputSources::default();
        let inputs = InputSources {
            plans: file.inputs.plans.unwrap_or(defaults.plans),
            planner_heartbeats: file
                .inputs
                .planner_heartbeats
                .unwrap_or(defaults.planner_heartbeats),
            fixes: file.inputs.fixes.unwrap_or(defaults.fixes),
            operator: file.inputs.operator.unwrap_or(defaults.operator),
        };
        let lidar_sensor = match file.lidar_sensor.as_deref() {
            None => None,
            Some(_) if lidar == LidarSource::None => {
                return Err(invalid(
                    "lidar_sensor",
                    "names a sensor but `lidar` is \"none\"".to_owned(),
                ));
            }
            Some(text) => Some(text.parse().map_err(|_| {
                invalid(
                    "lidar_sensor",
                    format!("{text:?} is not an IP address (the sensor's, e.g. 192.168.1.201)"),
                )
            })?),
        };
        let deployment = Self {
            lidar_sensor,
            inputs,
            lidar,
            source: path.to_owned(),
            namespace: file.namespace,
            map: resolve(file.map),
            robot: file.robot.map(resolve),
            model: resolve(file.model),
            can,
            arm: file.arm,
            clock: file.clock,
            planner: PlannerSettings {
                method,
                paper_smp: file.planner.paper_smp,
                retry: file.planner.retry,
            },
            seed: file.seed,
        };
        deployment.validate()?;
        Ok(deployment)
    }

    /// A deployment for tests and HIL without a file: `namespace`, the scene file `map`, the
    /// paper's robot, the model `model`, virtual CAN bus `<namespace>-can`, arm on loopback at
    /// the UR ports, wall clock, GROP without retry, seed 0.
    pub fn local(namespace: &str, map: impl Into<PathBuf>, model: impl Into<PathBuf>) -> Self {
        Self {
            source: PathBuf::new(),
            namespace: namespace.to_owned(),
            map: map.into(),
            robot: None,
            model: model.into(),
            can: CanSpec::Virtual {
                bus: format!("{namespace}-can").replace('/', "-"),
            },
            arm: ArmAddress::standard("127.0.0.1"),
            clock: default_clock(),
            planner: PlannerSettings::default(),
            seed: 0,
            lidar: LidarSource::None,
            inputs: InputSources::default(),
            lidar_sensor: None,
        }
    }

    /// Checks every value; the error names the field.
    pub fn validate(&self) -> Result<(), DeploymentError> {
        let invalid = |field: &'static str, reason: String| DeploymentError::Invalid {
            path: self.source.clone(),
            field,
            reason,
        };
        let ns = &self.namespace;
        let ns_ok = !ns.is_empty()
            && ns.len() <= 64
            && !ns.starts_with('/')
            && !ns.ends_with('/')
            && !ns.contains("//")
            && ns
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_./".contains(&b));
        if !ns_ok {
            return Err(invalid(
                "namespace",
                format!(
                    "{ns:?} must be 1-64 characters of letters, digits, `-`, `_`, `.`, `/` (not at the ends)"
                ),
            ));
        }
        for (field, path) in [("map", Some(&self.map)), ("model", Some(&self.model))]
            .into_iter()
            .chain([("robot", self.robot.as_ref())])
        {
            if path.is_some_and(|p| p.as_os_str().is_empty()) {
                return Err(invalid(field, "is an empty path".to_owned()));
            }
        }
        check_clock_spec(&self.clock).map_err(|reason| invalid("clock", reason))?;
        for (field, node) in [
            ("inputs.plans", &self.inputs.plans),
            ("inputs.planner_heartbeats", &self.inputs.planner_heartbeats),
            ("inputs.fixes", &self.inputs.fixes),
            ("inputs.operator", &self.inputs.operator),
        ] {
            let ok = !node.is_empty()
                && node.len() <= 64
                && node
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b));
            if !ok {
                return Err(invalid(
                    field,
                    format!("{node:?} must be a node name of 1-64 letters, digits, `-`, `_`, `.`"),
                ));
            }
        }
        if self.arm.host.trim().is_empty() || self.arm.host.contains(char::is_whitespace) {
            return Err(invalid(
                "arm.host",
                format!("{:?} is not a host name or address", self.arm.host),
            ));
        }
        let ports = [
            ("arm.rtde_port", self.arm.rtde_port),
            ("arm.dashboard_port", self.arm.dashboard_port),
            ("arm.script_port", self.arm.script_port),
            ("arm.gripper_port", self.arm.gripper_port),
        ];
        for (i, (field, port)) in ports.iter().enumerate() {
            if *port == 0 {
                return Err(invalid(field, "must not be 0".to_owned()));
            }
            if let Some((other, _)) = ports[..i].iter().find(|(_, p)| p == port) {
                return Err(invalid(field, format!("{port} is also {other}")));
            }
        }
        Ok(())
    }

    /// Loads the map/task scene file.
    pub fn load_scene(&self) -> Result<world::Scene, world::SceneError> {
        world::Scene::load(&self.map)
    }

    /// Loads the robot file, or the paper's robot when none is named.
    pub fn load_robot(&self) -> Result<world::RobotConfig, world::RobotError> {
        match &self.robot {
            Some(path) => world::RobotConfig::load(path),
            None => Ok(world::RobotConfig::default()),
        }
    }
}

/// `wall` or `sim:<name>` (the forms `grop_clock::open` takes).
fn check_clock_spec(spec: &str) -> Result<(), String> {
    if spec == "wall" {
        return Ok(());
    }
    match spec.strip_prefix("sim:") {
        Some(name)
            if !name.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b)) =>
        {
            Ok(())
        }
        _ => Err(format!("{spec:?} is not `wall` or `sim:<name>`")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FULL: &str = r#"
namespace = "robot"
map = "scene.toml"
robot = "/etc/grop/robot.toml"
model = "../models/psi-fcn.onnx"
can = "socketcan:can0"
clock = "sim:hil-1"
seed = 42
lidar = "udp:0.0.0.0:2368"

[arm]
host = "192.168.1.10"
rtde_port = 30004

[planner]
method = "fcn-planning"
paper_smp = true
retry = "replan"
"#;

    fn parse(text: &str) -> Result<Deployment, DeploymentError> {
        Deployment::from_toml_str(text, Path::new("/srv/grop/deployment.toml"))
    }

    #[test]
    fn a_file_larger_than_the_cap_is_refused_before_it_is_read_whole() {
        let dir = std::env::temp_dir().join(format!("grop-deploy-cap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("deployment.toml");
        // A valid file padded with a comment past the cap.
        let mut text = FULL.to_owned();
        text.push('#');
        text.push_str(&"x".repeat(MAX_DEPLOYMENT_FILE_BYTES as usize));
        std::fs::write(&path, &text).unwrap();
        let e = Deployment::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("larger than") && e.contains("deployment.toml"),
            "{e}"
        );
        // A file that never ends (a character device) is refused the same way.
        let e = Deployment::load("/dev/zero").unwrap_err().to_string();
        assert!(e.contains("larger than"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_full_file_loads_with_paths_resolved() {
        let d = parse(FULL).unwrap();
        assert_eq!(d.namespace, "robot");
        assert_eq!(d.map, Path::new("/srv/grop/scene.toml"));
        assert_eq!(d.robot.as_deref(), Some(Path::new("/etc/grop/robot.toml")));
        assert_eq!(d.model, Path::new("/srv/grop/../models/psi-fcn.onnx"));
        assert_eq!(
            d.can,
            CanSpec::SocketCan {
                ifname: "can0".into()
            }
        );
        assert_eq!(d.clock, "sim:hil-1");
        assert_eq!(d.seed, 42);
        assert_eq!(d.arm.dashboard_port, 29999);
        assert_eq!(d.planner.method, MethodKind::FcnPlanning);
        assert!(d.planner.paper_smp);
        assert_eq!(d.planner.retry, RetryPolicy::Replan);
        assert_eq!(d.lidar, LidarSource::Udp("0.0.0.0:2368".into()));
    }

    #[test]
    fn the_inputs_name_their_publishers_and_default_to_the_onboard_nodes() {
        let d = parse(FULL).unwrap();
        assert_eq!(d.inputs, InputSources::default());
        assert_eq!(d.inputs.plans, "grop-planner");
        let named = format!("{FULL}\n[inputs]\nfixes = \"world\"\n");
        let d = parse(&named).unwrap();
        assert_eq!(d.inputs.fixes, "world");
        assert_eq!(d.inputs.planner_heartbeats, "grop-planner");
        let bad = format!("{FULL}\n[inputs]\nplans = \"a b\"\n");
        let message = parse(&bad).unwrap_err().to_string();
        assert!(message.contains("`inputs.plans`"), "{message}");
        let operator = format!("{FULL}\n[inputs]\noperator = \"world\"\n");
        assert_eq!(parse(&operator).unwrap().inputs.operator, "world");
        assert_eq!(d.inputs.operator, "grop-enable", "the default operator");
        let unknown = format!("{FULL}\n[inputs]\ncamera = \"x\"\n");
        assert!(parse(&unknown).is_err());
    }

    #[test]
    fn the_lidar_sensor_is_an_ip_address_and_needs_a_lidar() {
        assert_eq!(parse(FULL).unwrap().lidar_sensor, None);
        let named = FULL.replace(
            "lidar = \"udp:0.0.0.0:2368\"\n",
            "lidar = \"udp:0.0.0.0:2368\"\nlidar_sensor = \"192.168.1.201\"\n",
        );
        assert_ne!(named, FULL);
        assert_eq!(
            parse(&named).unwrap().lidar_sensor,
            Some("192.168.1.201".parse().unwrap())
        );
        let bad = named.replace("192.168.1.201", "sensor");
        let message = parse(&bad).unwrap_err().to_string();
        assert!(message.contains("`lidar_sensor`"), "{message}");
        let blind = named.replace("udp:0.0.0.0:2368", "none");
        let message = parse(&blind).unwrap_err().to_string();
        assert!(message.contains("`lidar_sensor`"), "{message}");
    }

    #[test]
    fn a_real_can_bus_needs_a_range_sensor_or_says_none() {
        let without = FULL.replace("lidar = \"udp:0.0.0.0:2368\"\n", "");
        assert_ne!(without, FULL);
        let message = parse(&without).unwrap_err().to_string();
        assert!(
            message.contains("`lidar`") && message.contains("range sensor"),
            "{message}"
        );
        let blind = FULL.replace("udp:0.0.0.0:2368", "none");
        assert_eq!(parse(&blind).unwrap().lidar, LidarSource::None);
        for bad in ["udp:2368", "udp:host:0", "tcp:a:1", "udp: :5"] {
            let message = parse(&FULL.replace("udp:0.0.0.0:2368", bad))
                .unwrap_err()
                .to_string();
            assert!(message.contains("`lidar`"), "{bad}: {message}");
        }
    }

    #[test]
    fn defaults_are_the_paper() {
        let d = parse(
            "namespace = \"r\"\nmap = \"s.toml\"\nmodel = \"m.onnx\"\ncan = \"vcan:bus-1\"\n[arm]\nhost = \"localhost\"\n",
        )
        .unwrap();
        assert_eq!(d.planner, PlannerSettings::default());
        assert_eq!(d.clock, "wall");
        assert_eq!(d.robot, None);
        assert_eq!(
            d.can,
            CanSpec::Virtual {
                bus: "bus-1".into()
            }
        );
    }

    #[test]
    fn errors_name_the_file_and_the_field() {
        let cases = [
            (FULL.replace("socketcan:can0", "can0"), "`can`"),
            (FULL.replace("sim:hil-1", "simulated"), "`clock`"),
            (FULL.replace("fcn-planning", "astar"), "`planner.method`"),
            (FULL.replace("\"robot\"", "\"/robot\""), "`namespace`"),
            (
                FULL.replace("rtde_port = 30004", "rtde_port = 29999"),
                "`arm.dashboard_port`",
            ),
            (FULL.replace("seed = 42", "seed = 42\ncolour = 1"), "colour"),
            (
                FULL.replace("retry = \"replan\"", "retry = \"often\""),
                "often",
            ),
        ];
        for (text, needle) in cases {
            let message = parse(&text).unwrap_err().to_string();
            assert!(message.contains("/srv/grop/deployment.toml"), "{message}");
            assert!(message.contains(needle), "{needle}: {message}");
        }
        let missing = Deployment::load("/nonexistent/deployment.toml").unwrap_err();
        assert!(matches!(missing, DeploymentError::Read { .. }));
    }

    #[test]
    fn local_deployments_validate() {
        let d = Deployment::local("test-1-2-x", "scene.toml", "model.onnx");
        d.validate().unwrap();
        assert_eq!(
            d.load_robot().unwrap().speed_mps,
            world::RobotConfig::default().speed_mps
        );
    }
}
