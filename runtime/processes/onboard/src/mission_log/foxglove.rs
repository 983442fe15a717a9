//! Foxglove's well-known schemas (`foxglove.FrameTransforms`, `foxglove.SceneUpdate`,
//! `foxglove.PosesInFrame`, `foxglove.Grid`, `foxglove.Log`, ...) in their JSON form: the message
//! types as serde structs, each schema's fields as one hand-written table ([`fields`]), the JSON
//! Schema the log and the live view advertise built from that table ([`json_schema`]), and a
//! check of a message against it ([`check`]: every field of the table present with its JSON
//! type, no other field).
//!
//! The table follows Foxglove's schema definitions (the `.proto` files of the PyPI package
//! `foxglove-schemas-protobuf` 0.4.0): field names in snake case, times and durations as
//! `{"sec", "nsec"}`, bytes as base64 strings, enums as their numbers. `.ci/mcap_check.py` parses
//! every message of these channels into the protobuf messages of that package, which refuses an
//! unknown field or a wrong type: the table cannot drift from Foxglove's without CI noticing.

use serde::Serialize;
use serde_json::{Map, Value, json};

/// A time or a duration (`{"sec", "nsec"}`).
#[derive(Serialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Time {
    /// Whole seconds.
    pub sec: u32,
    /// Nanoseconds, below 1e9.
    pub nsec: u32,
}

impl Time {
    /// The time of a clock reading in nanoseconds.
    pub fn from_ns(ns: u64) -> Self {
        Self {
            sec: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// `foxglove.Vector3` (also `foxglove.Point3`: the same fields).
#[derive(Serialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// A point or vector.
pub fn v3(x: f64, y: f64, z: f64) -> Vector3 {
    Vector3 { x, y, z }
}

/// `foxglove.Vector2`.
#[derive(Serialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Vector2 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
}

/// `foxglove.Quaternion`.
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self::yaw(0.0)
    }
}

impl Quaternion {
    /// A rotation about +z.
    pub fn yaw(rad: f64) -> Self {
        let (s, c) = (0.5 * rad).sin_cos();
        Self {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }
}

/// `foxglove.Pose`.
#[derive(Serialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// Position.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

impl Pose {
    /// A pose on the floor plane: (x, y, z) turned by `yaw` about +z.
    pub fn planar(x: f64, y: f64, z: f64, yaw: f64) -> Self {
        Self {
            position: v3(x, y, z),
            orientation: Quaternion::yaw(yaw),
        }
    }
}

/// `foxglove.Color` (0..1).
#[derive(Serialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Color {
    /// Red.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
    /// Alpha (1 opaque).
    pub a: f64,
}

/// A colour from 8-bit RGB and an alpha.
pub fn rgba(r: u8, g: u8, b: u8, a: f64) -> Color {
    Color {
        r: f64::from(r) / 255.0,
        g: f64::from(g) / 255.0,
        b: f64::from(b) / 255.0,
        a,
    }
}

/// `foxglove.FrameTransform`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct FrameTransform {
    /// When.
    pub timestamp: Time,
    /// The parent frame.
    pub parent_frame_id: String,
    /// The child frame.
    pub child_frame_id: String,
    /// The child's origin in the parent frame.
    pub translation: Vector3,
    /// The child's rotation in the parent frame.
    pub rotation: Quaternion,
}

/// `foxglove.FrameTransforms`.
#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct FrameTransforms {
    /// The transforms.
    pub transforms: Vec<FrameTransform>,
}

/// `foxglove.KeyValuePair`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct KeyValuePair {
    /// Key.
    pub key: String,
    /// Value.
    pub value: String,
}

/// `foxglove.ArrowPrimitive` (along the pose's +x).
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct ArrowPrimitive {
    /// Where the arrow's tail is and where it points.
    pub pose: Pose,
    /// Shaft length (m).
    pub shaft_length: f64,
    /// Shaft diameter (m).
    pub shaft_diameter: f64,
    /// Head length (m).
    pub head_length: f64,
    /// Head diameter (m).
    pub head_diameter: f64,
    /// Colour.
    pub color: Color,
}

/// `foxglove.CubePrimitive` (the pose is the box's centre).
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct CubePrimitive {
    /// Centre and orientation.
    pub pose: Pose,
    /// Extents (m).
    pub size: Vector3,
    /// Colour.
    pub color: Color,
}

/// `foxglove.SpherePrimitive`.
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct SpherePrimitive {
    /// Centre.
    pub pose: Pose,
    /// Diameters (m).
    pub size: Vector3,
    /// Colour.
    pub color: Color,
}

/// `foxglove.CylinderPrimitive` (axis along the pose's +z).
#[derive(Serialize, Clone, Copy, Debug, PartialEq)]
pub struct CylinderPrimitive {
    /// Centre.
    pub pose: Pose,
    /// Bounding box (m).
    pub size: Vector3,
    /// Bottom diameter as a share of the box.
    pub bottom_scale: f64,
    /// Top diameter as a share of the box.
    pub top_scale: f64,
    /// Colour.
    pub color: Color,
}

/// `foxglove.LinePrimitive`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct LinePrimitive {
    /// 0 line strip, 1 line loop, 2 line list.
    #[serde(rename = "type")]
    pub kind: u32,
    /// Origin of the points.
    pub pose: Pose,
    /// Thickness (m, or px when scale-invariant).
    pub thickness: f64,
    /// Thickness in pixels.
    pub scale_invariant: bool,
    /// The points.
    pub points: Vec<Vector3>,
    /// Colour.
    pub color: Color,
    /// Per-point colours (empty: `color`).
    pub colors: Vec<Color>,
    /// Indices into `points` (empty: all in order).
    pub indices: Vec<u32>,
}

/// `foxglove.TextPrimitive`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct TextPrimitive {
    /// Where.
    pub pose: Pose,
    /// Always facing the viewer.
    pub billboard: bool,
    /// Size (px when scale-invariant).
    pub font_size: f64,
    /// Size in pixels.
    pub scale_invariant: bool,
    /// Colour.
    pub color: Color,
    /// The text.
    pub text: String,
}

/// `foxglove.SceneEntity`. Triangle lists and models are never used (always empty).
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct SceneEntity {
    /// When.
    pub timestamp: Time,
    /// The frame the primitives are in.
    pub frame_id: String,
    /// Unique per topic: a later entity with the same id replaces it.
    pub id: String,
    /// How long it shows (zero: until replaced or deleted).
    pub lifetime: Time,
    /// Moves with its frame (true) or stays where the frame was.
    pub frame_locked: bool,
    /// Key-value pairs shown on selection.
    pub metadata: Vec<KeyValuePair>,
    /// Arrows.
    pub arrows: Vec<ArrowPrimitive>,
    /// Boxes.
    pub cubes: Vec<CubePrimitive>,
    /// Spheres.
    pub spheres: Vec<SpherePrimitive>,
    /// Cylinders.
    pub cylinders: Vec<CylinderPrimitive>,
    /// Lines.
    pub lines: Vec<LinePrimitive>,
    /// Triangle lists (unused).
    pub triangles: [u8; 0],
    /// Texts.
    pub texts: Vec<TextPrimitive>,
    /// Models (unused).
    pub models: [u8; 0],
}

impl SceneEntity {
    /// An empty entity.
    pub fn new(timestamp: Time, frame_id: &str, id: String) -> Self {
        Self {
            timestamp,
            frame_id: frame_id.to_owned(),
            id,
            lifetime: Time::default(),
            frame_locked: false,
            metadata: Vec::new(),
            arrows: Vec::new(),
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines: Vec::new(),
            triangles: [],
            texts: Vec::new(),
            models: [],
        }
    }
}

/// `foxglove.SceneEntityDeletion`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct SceneEntityDeletion {
    /// When.
    pub timestamp: Time,
    /// 0 the entity named `id`, 1 all entities.
    #[serde(rename = "type")]
    pub kind: u32,
    /// The entity (with type 0).
    pub id: String,
}

/// `foxglove.SceneUpdate`.
#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct SceneUpdate {
    /// Deletions, applied first.
    pub deletions: Vec<SceneEntityDeletion>,
    /// Entities added or replaced.
    pub entities: Vec<SceneEntity>,
}

/// `foxglove.PosesInFrame`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct PosesInFrame {
    /// When.
    pub timestamp: Time,
    /// Frame of the poses.
    pub frame_id: String,
    /// The poses, in order.
    pub poses: Vec<Pose>,
}

/// `foxglove.PackedElementField`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct PackedElementField {
    /// Name.
    pub name: String,
    /// Byte offset within a cell.
    pub offset: u32,
    /// Numeric type: 7 FLOAT32, 8 FLOAT64 (Foxglove's `NumericType`).
    #[serde(rename = "type")]
    pub kind: u32,
}

/// `PackedElementField` type FLOAT32.
pub const FLOAT32: u32 = 7;

/// `foxglove.Grid`: a 2D grid of cells, row after row, the first cell at the pose's origin.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct Grid {
    /// When.
    pub timestamp: Time,
    /// Frame of the pose.
    pub frame_id: String,
    /// Origin (the first cell's corner) and orientation of the grid.
    pub pose: Pose,
    /// Cells per row.
    pub column_count: u32,
    /// Size of a cell (m).
    pub cell_size: Vector2,
    /// Bytes per row.
    pub row_stride: u32,
    /// Bytes per cell.
    pub cell_stride: u32,
    /// The fields of a cell.
    pub fields: Vec<PackedElementField>,
    /// The cells (base64).
    pub data: String,
}

/// `foxglove.PointCloud`: points packed one after the other, each `point_stride` bytes.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct PointCloud {
    /// When.
    pub timestamp: Time,
    /// Frame of the pose.
    pub frame_id: String,
    /// Origin of the points in the frame.
    pub pose: Pose,
    /// Bytes per point.
    pub point_stride: u32,
    /// The fields of a point.
    pub fields: Vec<PackedElementField>,
    /// The points (base64).
    pub data: String,
}

/// `foxglove.RawImage`: rows of pixels, `step` bytes each.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct RawImage {
    /// When.
    pub timestamp: Time,
    /// Frame of the camera (for the 3D panel; an image no camera took names none).
    pub frame_id: String,
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// `rgb8`, `mono8`, ...
    pub encoding: String,
    /// Bytes per row.
    pub step: u32,
    /// The pixels (base64).
    pub data: String,
}

/// `foxglove.Log`.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct Log {
    /// When.
    pub timestamp: Time,
    /// 1 debug, 2 info, 3 warning, 4 error, 5 fatal.
    pub level: u32,
    /// The message.
    pub message: String,
    /// Who (the process).
    pub name: String,
    /// Source file (empty).
    pub file: String,
    /// Source line (0).
    pub line: u32,
}

/// `foxglove.Log` levels.
pub mod level {
    /// Information.
    pub const INFO: u32 = 2;
    /// Something went wrong and was handled.
    pub const WARNING: u32 = 3;
    /// Something went wrong that stops or endangers the mission.
    pub const ERROR: u32 = 4;
}

/// What a field holds, in the JSON form of a Foxglove schema.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A number (float64, float32).
    Num,
    /// An integer (uint32, fixed32, enums).
    Int,
    /// A string.
    Str,
    /// A boolean.
    Bool,
    /// Bytes: a base64 string.
    Bytes,
    /// A time or a duration: `{"sec", "nsec"}`.
    Time,
    /// A message of the named schema (without `foxglove.`).
    Msg(&'static str),
    /// A list of numbers.
    Nums,
    /// A list of integers.
    Ints,
    /// A list of messages of the named schema.
    Msgs(&'static str),
}

use Kind::{Bool, Bytes, Int, Msg, Msgs, Num, Nums, Str};

/// The fields of a Foxglove schema (name without `foxglove.`), as Foxglove defines them; `None`
/// for a schema this module does not know.
#[allow(clippy::too_many_lines, reason = "one table of every schema's fields")]
pub fn fields(schema: &str) -> Option<&'static [(&'static str, Kind)]> {
    const T: Kind = Kind::Time;
    Some(match schema {
        "Vector2" => &[("x", Num), ("y", Num)],
        "Vector3" | "Point3" => &[("x", Num), ("y", Num), ("z", Num)],
        "Quaternion" => &[("x", Num), ("y", Num), ("z", Num), ("w", Num)],
        "Pose" => &[
            ("position", Msg("Vector3")),
            ("orientation", Msg("Quaternion")),
        ],
        "Color" => &[("r", Num), ("g", Num), ("b", Num), ("a", Num)],
        "KeyValuePair" => &[("key", Str), ("value", Str)],
        "FrameTransform" => &[
            ("timestamp", T),
            ("parent_frame_id", Str),
            ("child_frame_id", Str),
            ("translation", Msg("Vector3")),
            ("rotation", Msg("Quaternion")),
        ],
        "FrameTransforms" => &[("transforms", Msgs("FrameTransform"))],
        "ArrowPrimitive" => &[
            ("pose", Msg("Pose")),
            ("shaft_length", Num),
            ("shaft_diameter", Num),
            ("head_length", Num),
            ("head_diameter", Num),
            ("color", Msg("Color")),
        ],
        "CubePrimitive" | "SpherePrimitive" => &[
            ("pose", Msg("Pose")),
            ("size", Msg("Vector3")),
            ("color", Msg("Color")),
        ],
        "CylinderPrimitive" => &[
            ("pose", Msg("Pose")),
            ("size", Msg("Vector3")),
            ("bottom_scale", Num),
            ("top_scale", Num),
            ("color", Msg("Color")),
        ],
        "LinePrimitive" => &[
            ("type", Int),
            ("pose", Msg("Pose")),
            ("thickness", Num),
            ("scale_invariant", Bool),
            ("points", Msgs("Point3")),
            ("color", Msg("Color")),
            ("colors", Msgs("Color")),
            ("indices", Kind::Ints),
        ],
        "TriangleListPrimitive" => &[
            ("pose", Msg("Pose")),
            ("points", Msgs("Point3")),
            ("color", Msg("Color")),
            ("colors", Msgs("Color")),
            ("indices", Kind::Ints),
        ],
        "TextPrimitive" => &[
            ("pose", Msg("Pose")),
            ("billboard", Bool),
            ("font_size", Num),
            ("scale_invariant", Bool),
            ("color", Msg("Color")),
            ("text", Str),
        ],
        "ModelPrimitive" => &[
            ("pose", Msg("Pose")),
            ("scale", Msg("Vector3")),
            ("color", Msg("Color")),
            ("override_color", Bool),
            ("url", Str),
            ("media_type", Str),
            ("data", Bytes),
        ],
        "SceneEntity" => &[
            ("timestamp", T),
            ("frame_id", Str),
            ("id", Str),
            ("lifetime", T),
            ("frame_locked", Bool),
            ("metadata", Msgs("KeyValuePair")),
            ("arrows", Msgs("ArrowPrimitive")),
            ("cubes", Msgs("CubePrimitive")),
            ("spheres", Msgs("SpherePrimitive")),
            ("cylinders", Msgs("CylinderPrimitive")),
            ("lines", Msgs("LinePrimitive")),
            ("triangles", Msgs("TriangleListPrimitive")),
            ("texts", Msgs("TextPrimitive")),
            ("models", Msgs("ModelPrimitive")),
        ],
        "SceneEntityDeletion" => &[("timestamp", T), ("type", Int), ("id", Str)],
        "SceneUpdate" => &[
            ("deletions", Msgs("SceneEntityDeletion")),
            ("entities", Msgs("SceneEntity")),
        ],
        "PosesInFrame" => &[("timestamp", T), ("frame_id", Str), ("poses", Msgs("Pose"))],
        "PackedElementField" => &[("name", Str), ("offset", Int), ("type", Int)],
        "Grid" => &[
            ("timestamp", T),
            ("frame_id", Str),
            ("pose", Msg("Pose")),
            ("column_count", Int),
            ("cell_size", Msg("Vector2")),
            ("row_stride", Int),
            ("cell_stride", Int),
            ("fields", Msgs("PackedElementField")),
            ("data", Bytes),
        ],
        "RawImage" => &[
            ("timestamp", T),
            ("frame_id", Str),
            ("width", Int),
            ("height", Int),
            ("encoding", Str),
            ("step", Int),
            ("data", Bytes),
        ],
        "Log" => &[
            ("timestamp", T),
            ("level", Int),
            ("message", Str),
            ("name", Str),
            ("file", Str),
            ("line", Int),
        ],
        "PointCloud" => &[
            ("timestamp", T),
            ("frame_id", Str),
            ("pose", Msg("Pose")),
            ("point_stride", Int),
            ("fields", Msgs("PackedElementField")),
            ("data", Bytes),
        ],
        "LaserScan" => &[
            ("timestamp", T),
            ("frame_id", Str),
            ("pose", Msg("Pose")),
            ("start_angle", Num),
            ("end_angle", Num),
            ("ranges", Nums),
            ("intensities", Nums),
        ],
        _ => return None,
    })
}

fn kind_schema(kind: Kind) -> Value {
    match kind {
        Kind::Num => json!({"type": "number"}),
        Kind::Int => json!({"type": "integer"}),
        Kind::Str => json!({"type": "string"}),
        Kind::Bool => json!({"type": "boolean"}),
        Kind::Bytes => json!({"type": "string", "contentEncoding": "base64"}),
        Kind::Time => json!({
            "type": "object", "title": "time",
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}
        }),
        Kind::Msg(name) => object_schema(name),
        Kind::Nums => json!({"type": "array", "items": {"type": "number"}}),
        Kind::Ints => json!({"type": "array", "items": {"type": "integer"}}),
        Kind::Msgs(name) => json!({"type": "array", "items": object_schema(name)}),
    }
}

fn object_schema(name: &str) -> Value {
    let mut properties = Map::new();
    for (field, kind) in fields(name).unwrap_or(&[]) {
        properties.insert((*field).to_owned(), kind_schema(*kind));
    }
    json!({"type": "object", "title": format!("foxglove.{name}"), "properties": properties})
}

/// The JSON Schema of the Foxglove schema `name` (`foxglove.X`), as a channel advertises it.
pub fn json_schema(name: &str) -> Value {
    let short = name.strip_prefix("foxglove.").unwrap_or(name);
    let mut schema = object_schema(short);
    if let Some(o) = schema.as_object_mut() {
        o.insert(
            "$schema".into(),
            json!("https://json-schema.org/draft/2020-12/schema"),
        );
    }
    schema
}

/// Checks `value` against the Foxglove schema `name` (`foxglove.X` or `X`): every field of
/// [`fields`] present with its JSON type, recursively, and no field that the schema lacks. The
/// error names the path of the first field that is wrong.
pub fn check(name: &str, value: &Value) -> Result<(), String> {
    let short = name.strip_prefix("foxglove.").unwrap_or(name);
    check_msg(short, value, short)
}

fn check_msg(name: &str, value: &Value, path: &str) -> Result<(), String> {
    let table = fields(name).ok_or_else(|| format!("{path}: no schema foxglove.{name}"))?;
    let object = value
        .as_object()
        .ok_or_else(|| format!("{path}: not an object"))?;
    for key in object.keys() {
        if !table.iter().any(|(f, _)| f == key) {
            return Err(format!("{path}.{key}: not a field of foxglove.{name}"));
        }
    }
    for (field, kind) in table {
        let at = format!("{path}.{field}");
        let v = object.get(*field).ok_or_else(|| format!("{at}: missing"))?;
        check_kind(*kind, v, &at)?;
    }
    Ok(())
}

fn check_kind(kind: Kind, v: &Value, at: &str) -> Result<(), String> {
    let ok = match kind {
        Kind::Num => v.is_number(),
        Kind::Int => v.is_u64() || v.is_i64(),
        Kind::Str | Kind::Bytes => v.is_string(),
        Kind::Bool => v.is_boolean(),
        Kind::Time => {
            let o = v.as_object();
            let part = |k: &str| o.and_then(|o| o.get(k)).is_some_and(Value::is_u64);
            o.is_some_and(|o| o.len() == 2) && part("sec") && part("nsec")
        }
        Kind::Msg(name) => return check_msg(name, v, at),
        Kind::Nums | Kind::Ints | Kind::Msgs(_) => {
            let items = v.as_array().ok_or_else(|| format!("{at}: not a list"))?;
            let item = match kind {
                Kind::Nums => Kind::Num,
                Kind::Ints => Kind::Int,
                Kind::Msgs(name) => Kind::Msg(name),
                _ => kind,
            };
            for (i, x) in items.iter().enumerate() {
                check_kind(item, x, &format!("{at}[{i}]"))?;
            }
            true
        }
    };
    if ok {
        Ok(())
    } else {
        Err(format!("{at}: {v} is not a {kind:?}"))
    }
}
