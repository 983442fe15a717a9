//! The scene file: room, tables, chairs, unloading targets, robot start.
//!
//! Format (TOML or JSON, chosen by the file extension; `format_version = 1`) is documented in
//! `docs/world.md`. Every field is checked on load: unknown fields, non-finite numbers,
//! overlapping furniture, targets off the banquet table and furniture outside the room are errors
//! that name the file and the field.

use std::path::{Path, PathBuf};

use planar::Pose2;
use serde::{Deserialize, Serialize};

pub use crate::file::InvalidField;
use crate::file::{self, FileEncoding, FileFailure, encoding_of, first_non_finite};
use crate::geometry::OrientedRect;

/// The scene format version this crate reads and writes.
pub const SCENE_FORMAT_VERSION: u32 = 1;

/// y of the banquet table's centre line (m). Fixed by the world-frame convention
/// (docs/architecture.md): every overhead view is centred on this line.
pub const TABLE_CENTER_Y_M: f64 = 6.0;

/// Longest side of a room a scene may have, m (the paper's room is 20 m x 12.2 m).
pub const MAX_ROOM_SIDE_M: f64 = 100.0;
/// Most chairs in a scene.
pub const MAX_CHAIRS: usize = 1000;
/// Most targets in a scene (the runtime's plan and task masks hold 64 objects).
pub const MAX_TARGETS: usize = 64;
/// Most segments of the banquet table.
pub const MAX_TABLE_SEGMENTS: u32 = 100;

/// A complete dinner-table world.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Must equal [`SCENE_FORMAT_VERSION`].
    pub format_version: u32,
    /// Free-form name (for pictures and logs).
    #[serde(default)]
    pub name: String,
    /// The room's walls: an axis-aligned rectangle.
    pub room: Room,
    /// The table the robot loads objects from.
    pub loading_table: LoadingTable,
    /// Where the base stands (facing the loading table) to load.
    pub loading_station: Point2,
    /// The long table the objects go to.
    pub banquet_table: BanquetTable,
    /// Chairs around the banquet table.
    #[serde(default)]
    pub chairs: Vec<Chair>,
    /// Where objects must be placed.
    #[serde(default)]
    pub targets: Vec<UnloadTarget>,
    /// The base's pose at the start of a task.
    pub robot_start: Pose2,
}

/// The room's inner wall faces (m).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Room {
    /// West wall, world x (m).
    pub x_min_m: f64,
    /// East wall, world x (m).
    pub x_max_m: f64,
    /// South wall, world y (m).
    pub y_min_m: f64,
    /// North wall, world y (m).
    pub y_max_m: f64,
}

/// The loading table: an axis-aligned box standing on the floor.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LoadingTable {
    /// Centre, world x (m).
    pub center_x_m: f64,
    /// Centre, world y (m).
    pub center_y_m: f64,
    /// Extent along world x (m).
    pub length_m: f64,
    /// Extent along world y (m).
    pub depth_m: f64,
    /// Height of the top above the floor (m).
    pub top_height_m: f64,
}

/// The banquet table: `segment_count` segments in a row along x, centred on
/// y = [`TABLE_CENTER_Y_M`]. Segments touch end to end, so for collisions it is one box.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BanquetTable {
    /// x of the middle of the row of segments (m).
    pub center_x_m: f64,
    /// Number of segments (the paper: 9).
    pub segment_count: u32,
    /// Length of one segment along x (m; the paper: 1.5).
    pub segment_length_m: f64,
    /// Depth across the table, along y (m; the paper: 0.4).
    pub depth_m: f64,
    /// Height of the top above the floor (m; the paper: 1.0).
    pub top_height_m: f64,
}

/// A chair: a box standing on the floor with a real footprint, rotated by its yaw.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Chair {
    /// Centre of the footprint, world x (m).
    pub x_m: f64,
    /// Centre of the footprint, world y (m).
    pub y_m: f64,
    /// Rotation about +z (rad); the chair's front (seat edge) points along its local +x.
    pub yaw_rad: f64,
    /// Footprint extent along the chair's local x (m).
    #[serde(default = "default_chair_size_m")]
    pub depth_m: f64,
    /// Footprint extent along the chair's local y (m).
    #[serde(default = "default_chair_size_m")]
    pub width_m: f64,
    /// Height of the top of the backrest (m); the arm must stay above it.
    #[serde(default = "default_chair_height_m")]
    pub height_m: f64,
}

/// Default chair footprint side (m): a typical banquet chair.
pub const DEFAULT_CHAIR_SIZE_M: f64 = 0.45;
/// Default chair backrest height (m).
pub const DEFAULT_CHAIR_HEIGHT_M: f64 = 0.9;

fn default_chair_size_m() -> f64 {
    DEFAULT_CHAIR_SIZE_M
}
fn default_chair_height_m() -> f64 {
    DEFAULT_CHAIR_HEIGHT_M
}

impl Chair {
    /// A chair of the default size.
    pub fn new(x_m: f64, y_m: f64, yaw_rad: f64) -> Self {
        Self {
            x_m,
            y_m,
            yaw_rad,
            depth_m: DEFAULT_CHAIR_SIZE_M,
            width_m: DEFAULT_CHAIR_SIZE_M,
            height_m: DEFAULT_CHAIR_HEIGHT_M,
        }
    }

    /// The chair's footprint on the floor.
    pub fn footprint(&self) -> OrientedRect {
        OrientedRect::new(self.x_m, self.y_m, self.depth_m, self.width_m, self.yaw_rad)
    }
}

/// Where an object must end up (world frame, m): normally (x_t, 6.0, 1.3).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct UnloadTarget {
    /// World x (m).
    pub x_m: f64,
    /// World y (m); must lie on the banquet table's top.
    pub y_m: f64,
    /// Height of the object's goal (m); must be above the table top.
    pub z_m: f64,
}

impl UnloadTarget {
    /// Default height of the object's goal above the floor (m): the authors' 1.3 m.
    pub const DEFAULT_Z_M: f64 = 1.3;

    /// A target on the table's centre line at the default height.
    pub fn on_center_line(x_m: f64) -> Self {
        Self {
            x_m,
            y_m: TABLE_CENTER_Y_M,
            z_m: Self::DEFAULT_Z_M,
        }
    }

    /// As the `[x, y, z]` array the trial simulator and planner take.
    pub fn as_array(&self) -> [f64; 3] {
        [self.x_m, self.y_m, self.z_m]
    }
}

/// A point on the floor (m).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Point2 {
    /// World x (m).
    pub x_m: f64,
    /// World y (m).
    pub y_m: f64,
}

impl Room {
    /// The paper's room: walls at x = +-10 m, y = -2.1 .. 10.1 m.
    pub fn paper() -> Self {
        Self {
            x_min_m: -10.0,
            x_max_m: 10.0,
            y_min_m: -2.1,
            y_max_m: 10.1,
        }
    }

    /// Whether the point is inside the walls (border included).
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        (self.x_min_m..=self.x_max_m).contains(&x_m) && (self.y_min_m..=self.y_max_m).contains(&y_m)
    }

    /// Whether the footprint lies completely inside the walls.
    pub fn contains_rect(&self, rect: &OrientedRect) -> bool {
        rect.inside_bounds(self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m)
    }
}

impl LoadingTable {
    /// The footprint on the floor.
    pub fn footprint(&self) -> OrientedRect {
        OrientedRect::new(
            self.center_x_m,
            self.center_y_m,
            self.length_m,
            self.depth_m,
            0.0,
        )
    }
}

impl BanquetTable {
    /// The paper's table: nine 1.5 m x 0.4 m segments centred on x = 0, top at 1.0 m.
    pub fn paper() -> Self {
        Self {
            center_x_m: 0.0,
            segment_count: 9,
            segment_length_m: 1.5,
            depth_m: 0.4,
            top_height_m: 1.0,
        }
    }

    /// Total length along x (m).
    pub fn length_m(&self) -> f64 {
        f64::from(self.segment_count) * self.segment_length_m
    }

    /// x of the west end (m).
    pub fn x_min_m(&self) -> f64 {
        self.center_x_m - 0.5 * self.length_m()
    }

    /// x of the east end (m).
    pub fn x_max_m(&self) -> f64 {
        self.center_x_m + 0.5 * self.length_m()
    }

    /// y of the near edge (m).
    pub fn y_min_m(&self) -> f64 {
        TABLE_CENTER_Y_M - 0.5 * self.depth_m
    }

    /// y of the far edge (m).
    pub fn y_max_m(&self) -> f64 {
        TABLE_CENTER_Y_M + 0.5 * self.depth_m
    }

    /// The whole table's footprint (the segments touch, so one rectangle).
    pub fn footprint(&self) -> OrientedRect {
        OrientedRect::new(
            self.center_x_m,
            TABLE_CENTER_Y_M,
            self.length_m(),
            self.depth_m,
            0.0,
        )
    }

    /// Footprints of the individual segments, west to east (for pictures).
    pub fn segment_footprints(&self) -> Vec<OrientedRect> {
        (0..self.segment_count)
            .map(|i| {
                let x = self.x_min_m() + (f64::from(i) + 0.5) * self.segment_length_m;
                OrientedRect::new(
                    x,
                    TABLE_CENTER_Y_M,
                    self.segment_length_m,
                    self.depth_m,
                    0.0,
                )
            })
            .collect()
    }

    /// Whether (x, y) lies on the table top (border included).
    pub fn top_contains(&self, x_m: f64, y_m: f64) -> bool {
        (self.x_min_m()..=self.x_max_m()).contains(&x_m)
            && (self.y_min_m()..=self.y_max_m()).contains(&y_m)
    }
}

/// Failure to read, parse, validate or write a scene file. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("scene file {path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The extension is neither `.toml` nor `.json`.
    #[error("scene file {path}: unknown format (use a .toml or .json file)")]
    UnknownExtension {
        /// The file.
        path: PathBuf,
    },
    /// The text is not a scene: syntax error, unknown or missing field, wrong type. The message
    /// names the field and the line.
    #[error("scene file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message (names the field and position).
        message: String,
    },
    /// The file was written for another format version.
    #[error(
        "scene file {path}: field `format_version`: found {found}, this build reads {supported}"
    )]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// A field holds a value that makes no sense for the world (NaN, overlap, off the table...).
    #[error("scene file {path}: field `{}`: {}", .invalid.field, .invalid.reason)]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Which field and why.
        invalid: InvalidField,
    },
    /// The file could not be written.
    #[error("scene file {path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The scene could not be serialised (a non-finite number that the format cannot hold).
    #[error("scene file {path}: cannot serialise: {message}")]
    Serialize {
        /// The file.
        path: PathBuf,
        /// The serialiser's message.
        message: String,
    },
}

impl SceneError {
    fn from_failure(failure: FileFailure, path: &Path) -> Self {
        let path = path.to_owned();
        match failure {
            FileFailure::UnknownExtension => SceneError::UnknownExtension { path },
            FileFailure::Read(source) => SceneError::Read { path, source },
            FileFailure::Parse(message) => SceneError::Parse { path, message },
            FileFailure::UnsupportedVersion { found, supported } => {
                SceneError::UnsupportedVersion {
                    path,
                    found,
                    supported,
                }
            }
            FileFailure::Invalid(invalid) => SceneError::Invalid { path, invalid },
        }
    }
}

impl Scene {
    /// The paper's fixed furniture with no chairs and no targets: room, loading table at the
    /// south, loading station (0, 1.05), robot start (0, 2) facing the banquet table.
    pub fn empty_paper_room() -> Self {
        Self {
            format_version: SCENE_FORMAT_VERSION,
            name: String::new(),
            room: Room::paper(),
            loading_table: LoadingTable {
                center_x_m: 0.0,
                center_y_m: 0.3,
                length_m: 1.5,
                depth_m: 0.6,
                top_height_m: 0.75,
            },
            loading_station: Point2 {
                x_m: 0.0,
                y_m: 1.05,
            },
            banquet_table: BanquetTable::paper(),
            chairs: Vec::new(),
            targets: Vec::new(),
            robot_start: Pose2 {
                x_m: 0.0,
                y_m: 2.0,
                yaw_rad: std::f64::consts::FRAC_PI_2,
            },
        }
    }

    /// Reads and validates a scene file (`.toml` or `.json`).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        file::load(
            path,
            SCENE_FORMAT_VERSION..=SCENE_FORMAT_VERSION,
            Scene::validate,
        )
        .map_err(|failure| SceneError::from_failure(failure, path))
    }

    fn parse_str(text: &str, encoding: FileEncoding, origin: &Path) -> Result<Scene, SceneError> {
        file::parse(
            text,
            encoding,
            SCENE_FORMAT_VERSION..=SCENE_FORMAT_VERSION,
            Scene::validate,
        )
        .map_err(|failure| SceneError::from_failure(failure, origin))
    }

    /// Parses and validates scene text in JSON; `origin` names the source in errors.
    pub fn from_json_str(text: &str, origin: impl AsRef<Path>) -> Result<Scene, SceneError> {
        Self::parse_str(text, FileEncoding::Json, origin.as_ref())
    }

    /// The scene as JSON text (as [`Self::save`] writes a `.json` file).
    pub fn to_json_string(&self) -> Result<String, SceneError> {
        serde_json::to_string_pretty(self).map_err(|e| SceneError::Serialize {
            path: PathBuf::from("<memory>"),
            message: e.to_string(),
        })
    }

    /// Parses and validates scene text in TOML; `origin` names the source in errors.
    pub fn from_toml_str(text: &str, origin: impl AsRef<Path>) -> Result<Scene, SceneError> {
        Self::parse_str(text, FileEncoding::Toml, origin.as_ref())
    }

    /// The scene as TOML text.
    pub fn to_toml_string(&self) -> Result<String, SceneError> {
        toml::to_string(self).map_err(|e| SceneError::Serialize {
            path: PathBuf::from("<memory>"),
            message: e.to_string(),
        })
    }

    /// Writes the scene (`.toml` or `.json`, by extension).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), SceneError> {
        let path = path.as_ref();
        let encoding = encoding_of(path).ok_or_else(|| SceneError::UnknownExtension {
            path: path.to_owned(),
        })?;
        let text = match encoding {
            FileEncoding::Toml => toml::to_string(self).map_err(|e| e.to_string()),
            FileEncoding::Json => serde_json::to_string_pretty(self).map_err(|e| e.to_string()),
        }
        .map_err(|message| SceneError::Serialize {
            path: path.to_owned(),
            message,
        })?;
        std::fs::write(path, text).map_err(|source| SceneError::Write {
            path: path.to_owned(),
            source,
        })
    }

    /// Checks every rule of the format (see `docs/world.md`); names the first bad field.
    #[allow(clippy::too_many_lines, reason = "one check per field, each naming it")]
    pub fn validate(&self) -> Result<(), InvalidField> {
        if self.format_version != SCENE_FORMAT_VERSION {
            return Err(InvalidField::new(
                "format_version",
                format!(
                    "found {}, this build reads {SCENE_FORMAT_VERSION}",
                    self.format_version
                ),
            ));
        }
        if let Some(field) = first_non_finite(self) {
            return Err(InvalidField::new(field, "not a finite number"));
        }
        let room = &self.room;
        if room.x_max_m - room.x_min_m < 1.0 || room.y_max_m - room.y_min_m < 1.0 {
            return Err(InvalidField::new(
                "room",
                "the walls must enclose at least 1 m x 1 m (x_min < x_max, y_min < y_max)",
            ));
        }
        // Bounds before anything is sized from the scene (the occupancy grid has a cell per
        // 0.1 m: a room 10^7 m long would ask for terabytes).
        if room.x_max_m - room.x_min_m > MAX_ROOM_SIDE_M
            || room.y_max_m - room.y_min_m > MAX_ROOM_SIDE_M
        {
            return Err(InvalidField::new(
                "room",
                format!("the walls may enclose at most {MAX_ROOM_SIDE_M} m x {MAX_ROOM_SIDE_M} m"),
            ));
        }
        if self.chairs.len() > MAX_CHAIRS {
            return Err(InvalidField::new(
                "chairs",
                format!("{} chairs, at most {MAX_CHAIRS}", self.chairs.len()),
            ));
        }
        if self.targets.len() > MAX_TARGETS {
            return Err(InvalidField::new(
                "targets",
                format!("{} targets, at most {MAX_TARGETS}", self.targets.len()),
            ));
        }
        if self.banquet_table.segment_count > MAX_TABLE_SEGMENTS {
            return Err(InvalidField::new(
                "banquet_table.segment_count",
                format!(
                    "{}, at most {MAX_TABLE_SEGMENTS}",
                    self.banquet_table.segment_count
                ),
            ));
        }

        let lt = &self.loading_table;
        positive("loading_table.length_m", lt.length_m)?;
        positive("loading_table.depth_m", lt.depth_m)?;
        positive("loading_table.top_height_m", lt.top_height_m)?;
        if !room.contains_rect(&lt.footprint()) {
            return Err(InvalidField::new("loading_table", "outside the room"));
        }

        let bt = &self.banquet_table;
        if bt.segment_count == 0 {
            return Err(InvalidField::new(
                "banquet_table.segment_count",
                "must be at least 1",
            ));
        }
        positive("banquet_table.segment_length_m", bt.segment_length_m)?;
        positive("banquet_table.depth_m", bt.depth_m)?;
        positive("banquet_table.top_height_m", bt.top_height_m)?;
        if !room.contains_rect(&bt.footprint()) {
            return Err(InvalidField::new("banquet_table", "outside the room"));
        }
        if lt.footprint().overlaps(&bt.footprint()) {
            return Err(InvalidField::new(
                "loading_table",
                "overlaps the banquet table",
            ));
        }

        let furniture = [
            ("loading_table", lt.footprint()),
            ("banquet_table", bt.footprint()),
        ];
        for (i, chair) in self.chairs.iter().enumerate() {
            positive(&format!("chairs[{i}].depth_m"), chair.depth_m)?;
            positive(&format!("chairs[{i}].width_m"), chair.width_m)?;
            positive(&format!("chairs[{i}].height_m"), chair.height_m)?;
            let fp = chair.footprint();
            if !room.contains_rect(&fp) {
                return Err(InvalidField::new(
                    format!("chairs[{i}]"),
                    "footprint outside the room",
                ));
            }
            if let Some((name, _)) = furniture.iter().find(|(_, f)| f.overlaps(&fp)) {
                return Err(InvalidField::new(
                    format!("chairs[{i}]"),
                    format!("overlaps the {}", name.replace('_', " ")),
                ));
            }
            if let Some(j) = self.chairs[..i]
                .iter()
                .position(|other| other.footprint().overlaps(&fp))
            {
                return Err(InvalidField::new(
                    format!("chairs[{i}]"),
                    format!("overlaps chairs[{j}]"),
                ));
            }
        }

        for (i, t) in self.targets.iter().enumerate() {
            if !bt.top_contains(t.x_m, t.y_m) {
                return Err(InvalidField::new(
                    format!("targets[{i}]"),
                    format!(
                        "({:.3}, {:.3}) is off the banquet table (x {:.2} .. {:.2}, y {:.2} .. {:.2})",
                        t.x_m,
                        t.y_m,
                        bt.x_min_m(),
                        bt.x_max_m(),
                        bt.y_min_m(),
                        bt.y_max_m()
                    ),
                ));
            }
            if t.z_m <= bt.top_height_m {
                return Err(InvalidField::new(
                    format!("targets[{i}].z_m"),
                    format!(
                        "{} m is not above the table top at {} m",
                        t.z_m, bt.top_height_m
                    ),
                ));
            }
        }

        let point_checks = [
            (
                "loading_station",
                self.loading_station.x_m,
                self.loading_station.y_m,
            ),
            ("robot_start", self.robot_start.x_m, self.robot_start.y_m),
        ];
        for (name, x, y) in point_checks {
            if !room.contains(x, y) {
                return Err(InvalidField::new(name, "outside the room"));
            }
            if self.point_on_furniture(x, y) {
                return Err(InvalidField::new(name, "stands on furniture"));
            }
        }
        Ok(())
    }

    /// Whether (x, y) lies on a table or a chair.
    pub fn point_on_furniture(&self, x_m: f64, y_m: f64) -> bool {
        self.loading_table.footprint().contains_point(x_m, y_m)
            || self.banquet_table.footprint().contains_point(x_m, y_m)
            || self
                .chairs
                .iter()
                .any(|c| c.footprint().contains_point(x_m, y_m))
    }

    /// Footprints of all furniture standing on the floor: the two tables, then the chairs.
    pub fn furniture_footprints(&self) -> Vec<OrientedRect> {
        let mut out = Vec::with_capacity(2 + self.chairs.len());
        out.push(self.loading_table.footprint());
        out.push(self.banquet_table.footprint());
        out.extend(self.chairs.iter().map(Chair::footprint));
        out
    }
}

fn positive(field: &str, value: f64) -> Result<(), InvalidField> {
    if value > 0.0 {
        Ok(())
    } else {
        Err(InvalidField::new(
            field,
            format!("must be positive, found {value}"),
        ))
    }
}
