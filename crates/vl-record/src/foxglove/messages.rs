//! Foxglove's message schemas as types: what each view is made of, in the
//! shape Foxglove's panels read (its JSON encoding: snake_case fields, times
//! as `{sec, nsec}`, bytes as base64, enums as integers). Their JSON Schemas
//! are generated from these same types, so a schema and its messages cannot
//! disagree; that both match Foxglove's own schemas is checked from outside
//! (tests/foxglove, with the official `@foxglove/schemas`).

use schemars::JsonSchema;
use serde::Serialize;

/// A time: seconds and nanoseconds since 1970.
#[derive(Debug, Clone, Copy, Default, Serialize, JsonSchema)]
pub(crate) struct Time {
    pub sec: u32,
    pub nsec: u32,
}

impl Time {
    pub(crate) fn at(ns: u64) -> Time {
        Time {
            sec: u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX),
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// Bytes, base64 in JSON.
#[derive(Debug, Clone, Default)]
pub(crate) struct Base64(pub Vec<u8>);

impl Serialize for Base64 {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use base64::Engine;
        s.serialize_str(&base64::engine::general_purpose::STANDARD.encode(&self.0))
    }
}

impl JsonSchema for Base64 {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "bytes".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({"type": "string", "contentEncoding": "base64"})
    }
}

#[derive(Debug, Clone, Copy, Default, Serialize, JsonSchema)]
pub(crate) struct Vector2 {
    pub x: f64,
    pub y: f64,
}

#[derive(Debug, Clone, Copy, Default, Serialize, JsonSchema)]
pub(crate) struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

#[derive(Debug, Clone, Copy, Serialize, JsonSchema)]
pub(crate) struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Quaternion {
    /// A heading: a turn about z.
    pub(crate) fn about_z(theta_rad: f64) -> Quaternion {
        let (s, c) = (theta_rad / 2.0).sin_cos();
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize, JsonSchema)]
pub(crate) struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

#[derive(Debug, Clone, Copy, Serialize, JsonSchema)]
pub(crate) struct Color {
    pub r: f64,
    pub g: f64,
    pub b: f64,
    pub a: f64,
}

pub(crate) const fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

#[derive(Debug, Clone, Copy, Serialize, JsonSchema)]
pub(crate) struct Point2 {
    pub x: f64,
    pub y: f64,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct KeyValuePair {
    pub key: String,
    pub value: String,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct CompressedImage {
    pub timestamp: Time,
    pub frame_id: String,
    pub data: Base64,
    pub format: String,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct PoseInFrame {
    pub timestamp: Time,
    pub frame_id: String,
    pub pose: Pose,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct PosesInFrame {
    pub timestamp: Time,
    pub frame_id: String,
    pub poses: Vec<Pose>,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct FrameTransform {
    pub timestamp: Time,
    pub parent_frame_id: String,
    pub child_frame_id: String,
    pub translation: Vector3,
    pub rotation: Quaternion,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct Log {
    pub timestamp: Time,
    /// 1 debug, 2 info, 3 warning, 4 error, 5 fatal.
    pub level: u8,
    pub message: String,
    pub name: String,
    pub file: String,
    pub line: u32,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct CircleAnnotation {
    pub timestamp: Time,
    pub position: Point2,
    pub diameter: f64,
    pub thickness: f64,
    pub fill_color: Color,
    pub outline_color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct PointsAnnotation {
    pub timestamp: Time,
    /// 1 points, 2 line loop, 3 line strip, 4 line list.
    #[serde(rename = "type")]
    pub kind: u8,
    pub points: Vec<Point2>,
    pub outline_color: Color,
    pub outline_colors: Vec<Color>,
    pub fill_color: Color,
    pub thickness: f64,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct TextAnnotation {
    pub timestamp: Time,
    pub position: Point2,
    pub text: String,
    pub font_size: f64,
    pub text_color: Color,
    pub background_color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct ImageAnnotations {
    pub circles: Vec<CircleAnnotation>,
    pub points: Vec<PointsAnnotation>,
    pub texts: Vec<TextAnnotation>,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct ArrowPrimitive {
    pub pose: Pose,
    pub shaft_length: f64,
    pub shaft_diameter: f64,
    pub head_length: f64,
    pub head_diameter: f64,
    pub color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct CubePrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct SpherePrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct CylinderPrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub bottom_scale: f64,
    pub top_scale: f64,
    pub color: Color,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct LinePrimitive {
    /// 0 strip, 1 loop, 2 list.
    #[serde(rename = "type")]
    pub kind: u8,
    pub pose: Pose,
    pub thickness: f64,
    pub scale_invariant: bool,
    pub points: Vec<Vector3>,
    pub color: Color,
    pub colors: Vec<Color>,
    pub indices: Vec<u32>,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct TriangleListPrimitive {
    pub pose: Pose,
    pub points: Vec<Vector3>,
    pub color: Color,
    pub colors: Vec<Color>,
    pub indices: Vec<u32>,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct TextPrimitive {
    pub pose: Pose,
    pub billboard: bool,
    pub font_size: f64,
    pub scale_invariant: bool,
    pub color: Color,
    pub text: String,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct ModelPrimitive {
    pub pose: Pose,
    pub scale: Vector3,
    pub color: Color,
    pub override_color: bool,
    pub url: String,
    pub media_type: String,
    pub data: Base64,
}

/// A duration (an entity's lifetime): zero is for ever.
#[derive(Debug, Clone, Copy, Default, Serialize, JsonSchema)]
pub(crate) struct Duration {
    pub sec: i32,
    pub nsec: u32,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct SceneEntity {
    pub timestamp: Time,
    pub frame_id: String,
    pub id: String,
    pub lifetime: Duration,
    pub frame_locked: bool,
    pub metadata: Vec<KeyValuePair>,
    pub arrows: Vec<ArrowPrimitive>,
    pub cubes: Vec<CubePrimitive>,
    pub spheres: Vec<SpherePrimitive>,
    pub cylinders: Vec<CylinderPrimitive>,
    pub lines: Vec<LinePrimitive>,
    pub triangles: Vec<TriangleListPrimitive>,
    pub texts: Vec<TextPrimitive>,
    pub models: Vec<ModelPrimitive>,
}

impl SceneEntity {
    /// An entity with no primitives yet.
    pub(crate) fn new(ns: u64, id: &str, frame_id: &str, frame_locked: bool) -> SceneEntity {
        SceneEntity {
            timestamp: Time::at(ns),
            frame_id: frame_id.to_owned(),
            id: id.to_owned(),
            lifetime: Duration::default(),
            frame_locked,
            metadata: Vec::new(),
            arrows: Vec::new(),
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Vec::new(),
            lines: Vec::new(),
            triangles: Vec::new(),
            texts: Vec::new(),
            models: Vec::new(),
        }
    }
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct SceneEntityDeletion {
    pub timestamp: Time,
    /// 0 the entity `id`, 1 every entity.
    #[serde(rename = "type")]
    pub kind: u8,
    pub id: String,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct SceneUpdate {
    pub deletions: Vec<SceneEntityDeletion>,
    pub entities: Vec<SceneEntity>,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct PackedElementField {
    pub name: String,
    pub offset: u32,
    /// 1 is UINT8.
    #[serde(rename = "type")]
    pub kind: u8,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct Grid {
    pub timestamp: Time,
    pub frame_id: String,
    /// The grid's corner: its first cell's, rows along +y.
    pub pose: Pose,
    pub column_count: u32,
    pub cell_size: Vector2,
    pub row_stride: u32,
    pub cell_stride: u32,
    pub fields: Vec<PackedElementField>,
    pub data: Base64,
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
#[allow(non_snake_case)] // Foxglove's names, as ROS's CameraInfo has them.
pub(crate) struct CameraCalibration {
    pub timestamp: Time,
    pub frame_id: String,
    pub width: u32,
    pub height: u32,
    pub distortion_model: String,
    pub D: Vec<f64>,
    pub K: [f64; 9],
    pub R: [f64; 9],
    pub P: [f64; 12],
}

#[derive(Debug, Clone, Serialize, JsonSchema)]
pub(crate) struct LaserScan {
    pub timestamp: Time,
    pub frame_id: String,
    pub pose: Pose,
    pub start_angle: f64,
    pub end_angle: f64,
    pub ranges: Vec<f64>,
    pub intensities: Vec<f64>,
}
