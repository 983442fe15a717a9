//! The robot file: base footprint, UR5e mount and placing settings, speeds and limits,
//! navigation noise, the success reward R.
//!
//! Format (TOML or JSON by extension, `format_version = 2`; version 1 files, written before the
//! range sensor, still load with the default [`LidarSpec`]) in `docs/world.md`; the default
//! file is `runtime/libraries/world/data/robot.toml` and equals [`RobotConfig::default`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use ur5e_kin::PlaceConfig;

use crate::file::{self, FileEncoding, FileFailure, encoding_of};
use crate::file::{InvalidField, first_non_finite};
use crate::geometry::OrientedRect;
use crate::lidar::LidarSpec;

/// The robot format version this crate writes (2: the `[lidar]` section).
pub const ROBOT_FORMAT_VERSION: u32 = 2;
/// The oldest robot format version this crate reads.
pub const OLDEST_ROBOT_FORMAT_VERSION: u32 = 1;

const SUPPORTED: std::ops::RangeInclusive<u32> = OLDEST_ROBOT_FORMAT_VERSION..=ROBOT_FORMAT_VERSION;

/// Everything about the robot that the world, the simulator and the planner need.
#[derive(Serialize, Deserialize, Clone, Debug)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// [`OLDEST_ROBOT_FORMAT_VERSION`] to [`ROBOT_FORMAT_VERSION`].
    pub format_version: u32,
    /// The mobile base's body seen from above.
    pub footprint: BaseFootprint,
    /// Arm mount on the base, gripper length and placing tolerance (ur5e-kin's settings).
    pub place: PlaceConfig,
    /// Cruise speed of the base (m/s); travel time C = path length / speed (paper: 0.2/0.4/0.8).
    pub speed_mps: f64,
    /// Linear acceleration limit of the base (m/s^2).
    pub accel_mps2: f64,
    /// Turning-rate limit of the base (rad/s).
    pub yaw_rate_radps: f64,
    /// Turning-acceleration limit of the base (rad/s^2).
    pub yaw_accel_radps2: f64,
    /// Deceleration of a safety stop (m/s^2): e-stop, kill switch, lost link, base fault...
    /// At least `accel_mps2` (the comfort deceleration), at most [`MAX_EMERGENCY_DECEL_MPS2`].
    /// Optional in the file; default [`DEFAULT_EMERGENCY_DECEL_MPS2`], the RMP's factory
    /// deceleration limit (what the base itself does on a lost link).
    #[serde(default = "default_emergency_decel")]
    pub emergency_decel_mps2: f64,
    /// Standard deviation of the realised base position around a navigation goal, per axis (m).
    pub nav_noise_sigma_m: f64,
    /// Reward R for a placed object in the utility U = R * F - C (paper eq. 3; 40).
    pub success_bonus_r: f64,
    /// How base collisions are decided in trials; default the real footprint (the paper).
    #[serde(default)]
    pub base_collision: BaseCollisionModel,
    /// Objects the base carries at once (its tray): a plan for more objects makes several trips
    /// to the loading station. Optional in the file; default [`DEFAULT_CARRY_CAPACITY`] (a tray
    /// of 3, one place setting), at most [`MAX_CARRY_CAPACITY`].
    #[serde(default = "default_carry_capacity")]
    pub carry_capacity: u32,
    /// The range sensor (format version 2; a version 1 file gets [`LidarSpec::default`]).
    #[serde(default)]
    pub lidar: LidarSpec,
}

/// The tray of the default robot: 3 objects (one place setting).
pub const DEFAULT_CARRY_CAPACITY: u32 = 3;
/// Most objects a robot file may claim to carry at once (the runtime's task masks hold 64).
pub const MAX_CARRY_CAPACITY: u32 = 64;

fn default_carry_capacity() -> u32 {
    DEFAULT_CARRY_CAPACITY
}

/// `emergency_decel_mps2` of a robot file without it: the RMP's factory deceleration limit
/// (and decel-to-zero rate), m/s^2.
pub const DEFAULT_EMERGENCY_DECEL_MPS2: f64 = 3.923;
/// Highest `emergency_decel_mps2`: the most deceleration the RMP's stored limit accepts, m/s^2.
pub const MAX_EMERGENCY_DECEL_MPS2: f64 = 7.848;

fn default_emergency_decel() -> f64 {
    DEFAULT_EMERGENCY_DECEL_MPS2
}

/// How the trial simulator decides whether the realised base pose collides.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum BaseCollisionModel {
    /// The base footprint (oriented rectangle) against the tables', chairs' and walls' real
    /// footprints. The paper's robot; our default.
    #[default]
    Footprint,
    /// The authors' code: a point robot that collides when its centre is within `radius_m`
    /// (their 0.3 m) of a chair's centre, stands on a table or leaves the room. Kept to compare
    /// datasets with theirs; navigation still plans with the footprint.
    ChairDiscs {
        /// Radius of the disc around each chair centre (m).
        radius_m: f64,
    },
}

/// The base's rectangular body, centred on the base frame origin (base centre on the floor,
/// x forward).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BaseFootprint {
    /// Extent along the heading (m).
    pub length_m: f64,
    /// Extent across the heading (m).
    pub width_m: f64,
    /// Height of the body (deck and arm column) the arm must not hit (m).
    pub body_height_m: f64,
}

impl BaseFootprint {
    /// Segway RMP 110 with its deck and the column carrying the arm, rounded up to a box:
    /// 0.60 m long, 0.55 m wide. The body reaches up to the arm's mounting plate.
    pub const RMP_110: BaseFootprint = BaseFootprint {
        length_m: 0.60,
        width_m: 0.55,
        body_height_m: 1.0,
    };

    /// The footprint at a base pose.
    pub fn at(&self, x_m: f64, y_m: f64, yaw_rad: f64) -> OrientedRect {
        OrientedRect::new(x_m, y_m, self.length_m, self.width_m, yaw_rad)
    }
}

impl Default for RobotConfig {
    /// The paper's robot: RMP 110 base, UR5e on ur5e-kin's default mount with a Robotiq 2F-140,
    /// 0.4 m/s, sigma = 0.1 m, R = 40.
    fn default() -> Self {
        let place = PlaceConfig::default();
        let footprint = BaseFootprint {
            // The body reaches up to the arm's mounting plate.
            body_height_m: place.mount.height_m,
            ..BaseFootprint::RMP_110
        };
        Self {
            format_version: ROBOT_FORMAT_VERSION,
            footprint,
            place,
            speed_mps: 0.4,
            accel_mps2: 0.5,
            yaw_rate_radps: 1.0,
            yaw_accel_radps2: 1.5,
            emergency_decel_mps2: DEFAULT_EMERGENCY_DECEL_MPS2,
            nav_noise_sigma_m: 0.1,
            success_bonus_r: 40.0,
            base_collision: BaseCollisionModel::Footprint,
            carry_capacity: DEFAULT_CARRY_CAPACITY,
            lidar: LidarSpec::default(),
        }
    }
}

/// Failure to read, parse, validate or write a robot file. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The file could not be read.
    #[error("robot file {path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The extension is neither `.toml` nor `.json`.
    #[error("robot file {path}: unknown format (use a .toml or .json file)")]
    UnknownExtension {
        /// The file.
        path: PathBuf,
    },
    /// Syntax error, unknown or missing field, wrong type (the message names field and line).
    #[error("robot file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// The file was written for another format version.
    #[error(
        "robot file {path}: field `format_version`: found {found}, this build reads {supported}"
    )]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A value out of its range (NaN, negative speed, mount outside the base...).
    #[error("robot file {path}: field `{}`: {}", .invalid.field, .invalid.reason)]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Which field and why.
        invalid: InvalidField,
    },
    /// The file could not be written.
    #[error("robot file {path}: cannot write: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// Highest `speed_mps` a robot file may give: the RMP's factory maximum velocity, m/s.
pub const MAX_SPEED_MPS: f64 = 2.2352;
/// Highest `accel_mps2`: the RMP's factory maximum acceleration, m/s^2.
pub const MAX_ACCEL_MPS2: f64 = 3.923;
/// Highest `yaw_rate_radps`: the RMP's factory maximum turn rate, rad/s.
pub const MAX_YAW_RATE_RADPS: f64 = 3.0;
/// Highest `yaw_accel_radps2`: the RMP's factory maximum turn acceleration, rad/s^2.
pub const MAX_YAW_ACCEL_RADPS2: f64 = 28.274;

impl RobotError {
    fn from_failure(failure: FileFailure, path: &Path) -> Self {
        let path = path.to_owned();
        match failure {
            FileFailure::UnknownExtension => RobotError::UnknownExtension { path },
            FileFailure::Read(source) => RobotError::Read { path, source },
            FileFailure::Parse(message) => RobotError::Parse { path, message },
            FileFailure::UnsupportedVersion { found, supported } => {
                RobotError::UnsupportedVersion {
                    path,
                    found,
                    supported,
                }
            }
            FileFailure::Invalid(invalid) => RobotError::Invalid { path, invalid },
        }
    }
}

impl RobotConfig {
    /// Reads and validates a robot file (`.toml` or `.json`).
    pub fn load(path: impl AsRef<Path>) -> Result<RobotConfig, RobotError> {
        let path = path.as_ref();
        file::load(path, SUPPORTED, RobotConfig::validate)
            .map_err(|failure| RobotError::from_failure(failure, path))
    }

    fn parse_str(
        text: &str,
        encoding: FileEncoding,
        origin: &Path,
    ) -> Result<RobotConfig, RobotError> {
        file::parse(text, encoding, SUPPORTED, RobotConfig::validate)
            .map_err(|failure| RobotError::from_failure(failure, origin))
    }

    /// Parses and validates robot text in JSON; `origin` names the source in errors.
    pub fn from_json_str(text: &str, origin: impl AsRef<Path>) -> Result<RobotConfig, RobotError> {
        Self::parse_str(text, FileEncoding::Json, origin.as_ref())
    }

    /// The configuration as JSON text (as [`Self::save`] writes a `.json` file).
    pub fn to_json_string(&self) -> Result<String, RobotError> {
        serde_json::to_string_pretty(self).map_err(|e| RobotError::Write {
            path: PathBuf::from("<memory>"),
            message: e.to_string(),
        })
    }

    /// Parses and validates robot text in TOML; `origin` names the source in errors.
    pub fn from_toml_str(text: &str, origin: impl AsRef<Path>) -> Result<RobotConfig, RobotError> {
        Self::parse_str(text, FileEncoding::Toml, origin.as_ref())
    }

    /// The configuration as TOML text.
    pub fn to_toml_string(&self) -> Result<String, RobotError> {
        toml::to_string(self).map_err(|e| RobotError::Write {
            path: PathBuf::from("<memory>"),
            message: e.to_string(),
        })
    }

    /// Writes the configuration (`.toml` or `.json`, by extension).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), RobotError> {
        let path = path.as_ref();
        let encoding = encoding_of(path).ok_or_else(|| RobotError::UnknownExtension {
            path: path.to_owned(),
        })?;
        let text = match encoding {
            FileEncoding::Toml => toml::to_string(self).map_err(|e| e.to_string()),
            FileEncoding::Json => serde_json::to_string_pretty(self).map_err(|e| e.to_string()),
        }
        .map_err(|message| RobotError::Write {
            path: path.to_owned(),
            message,
        })?;
        std::fs::write(path, text).map_err(|e| RobotError::Write {
            path: path.to_owned(),
            message: e.to_string(),
        })
    }

    /// Checks every field's range (see `docs/world.md`); names the first bad field.
    #[allow(clippy::too_many_lines, reason = "one check per field, each naming it")]
    pub fn validate(&self) -> Result<(), InvalidField> {
        if !SUPPORTED.contains(&self.format_version) {
            return Err(InvalidField::new(
                "format_version",
                format!(
                    "found {}, this build reads {OLDEST_ROBOT_FORMAT_VERSION} to {ROBOT_FORMAT_VERSION}",
                    self.format_version
                ),
            ));
        }
        if let Some(field) = first_non_finite(self) {
            return Err(InvalidField::new(field, "not a finite number"));
        }
        let positive = [
            ("footprint.length_m", self.footprint.length_m),
            ("footprint.width_m", self.footprint.width_m),
            ("footprint.body_height_m", self.footprint.body_height_m),
            ("place.mount.height_m", self.place.mount.height_m),
            ("speed_mps", self.speed_mps),
            ("accel_mps2", self.accel_mps2),
            ("yaw_rate_radps", self.yaw_rate_radps),
            ("yaw_accel_radps2", self.yaw_accel_radps2),
            ("emergency_decel_mps2", self.emergency_decel_mps2),
        ];
        for (field, value) in positive {
            if value <= 0.0 {
                return Err(InvalidField::new(
                    field,
                    format!("must be positive, found {value}"),
                ));
            }
        }
        // What the Segway RMP can be set to do at most (its stored limits' factory values,
        // docs/rmp.md): a robot file asking for more is a typo, not a faster robot.
        let at_most = [
            ("speed_mps", self.speed_mps, MAX_SPEED_MPS),
            ("accel_mps2", self.accel_mps2, MAX_ACCEL_MPS2),
            ("yaw_rate_radps", self.yaw_rate_radps, MAX_YAW_RATE_RADPS),
            (
                "yaw_accel_radps2",
                self.yaw_accel_radps2,
                MAX_YAW_ACCEL_RADPS2,
            ),
            (
                "emergency_decel_mps2",
                self.emergency_decel_mps2,
                MAX_EMERGENCY_DECEL_MPS2,
            ),
        ];
        for (field, value, max) in at_most {
            if value > max {
                return Err(InvalidField::new(
                    field,
                    format!("at most {max} (the base's own limit), found {value}"),
                ));
            }
        }
        // A safety stop is never gentler than a comfortable one (the base decelerates at
        // `accel_mps2` in normal driving).
        if self.emergency_decel_mps2 < self.accel_mps2 {
            return Err(InvalidField::new(
                "emergency_decel_mps2",
                format!(
                    "at least accel_mps2 ({}, the comfort deceleration), found {}",
                    self.accel_mps2, self.emergency_decel_mps2
                ),
            ));
        }
        let non_negative = [
            ("nav_noise_sigma_m", self.nav_noise_sigma_m),
            ("success_bonus_r", self.success_bonus_r),
            ("place.tcp_offset_m", self.place.tcp_offset_m),
            ("place.down_tolerance_rad", self.place.down_tolerance_rad),
        ];
        for (field, value) in non_negative {
            if value < 0.0 {
                return Err(InvalidField::new(
                    field,
                    format!("must not be negative, found {value}"),
                ));
            }
        }
        if let BaseCollisionModel::ChairDiscs { radius_m } = self.base_collision
            && radius_m <= 0.0
        {
            return Err(InvalidField::new(
                "base_collision.radius_m",
                format!("must be positive, found {radius_m}"),
            ));
        }
        if self.carry_capacity == 0 || self.carry_capacity > MAX_CARRY_CAPACITY {
            return Err(InvalidField::new(
                "carry_capacity",
                format!(
                    "must be in 1..={MAX_CARRY_CAPACITY}, found {}",
                    self.carry_capacity
                ),
            ));
        }
        if let Err((field, reason)) = self.lidar.check() {
            return Err(InvalidField::new(field, reason));
        }
        if self.footprint.length_m > 3.0 || self.footprint.width_m > 3.0 {
            return Err(InvalidField::new(
                "footprint",
                "a base larger than 3 m is not a mobile manipulator",
            ));
        }
        let mount = &self.place.mount;
        if mount.forward_m.abs() > 0.5 * self.footprint.length_m
            || mount.lateral_m.abs() > 0.5 * self.footprint.width_m
        {
            return Err(InvalidField::new(
                "place.mount",
                format!(
                    "arm base ({:.3}, {:.3}) m lies outside the {:.2} x {:.2} m footprint",
                    mount.forward_m,
                    mount.lateral_m,
                    self.footprint.length_m,
                    self.footprint.width_m
                ),
            ));
        }
        if mount.height_m > 3.0 {
            return Err(InvalidField::new(
                "place.mount.height_m",
                format!("{} m is above any ceiling", mount.height_m),
            ));
        }
        if self.place.down_tolerance_rad > std::f64::consts::PI {
            return Err(InvalidField::new(
                "place.down_tolerance_rad",
                "must be at most pi",
            ));
        }
        Ok(())
    }

    /// Travel time (s) along a path of `length_m` at the cruise speed: C of paper eq. 3 for one
    /// navigation action. Acceleration is ignored, as in the paper's costs.
    pub fn travel_time_s(&self, length_m: f64) -> f64 {
        length_m / self.speed_mps
    }
}
