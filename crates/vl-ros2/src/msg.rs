//! ROS 2 message definitions: the vendored `.msg` files (`ros2-msgs/`),
//! read as rosidl reads them, and their RIHS01 type hashes (REP 2011):
//! SHA-256 over the type description of a message and every message it
//! holds, written as JSON the way rosidl writes it for hashing.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use sha2::{Digest, Sha256};
use thiserror::Error;

/// The vendored definitions, by full type name.
const VENDORED: &[(&str, &str)] = &[
    (
        "builtin_interfaces/msg/Time",
        include_str!("../ros2-msgs/builtin_interfaces/msg/Time.msg"),
    ),
    (
        "std_msgs/msg/Header",
        include_str!("../ros2-msgs/std_msgs/msg/Header.msg"),
    ),
    (
        "geometry_msgs/msg/Point",
        include_str!("../ros2-msgs/geometry_msgs/msg/Point.msg"),
    ),
    (
        "geometry_msgs/msg/Quaternion",
        include_str!("../ros2-msgs/geometry_msgs/msg/Quaternion.msg"),
    ),
    (
        "geometry_msgs/msg/Pose",
        include_str!("../ros2-msgs/geometry_msgs/msg/Pose.msg"),
    ),
    (
        "geometry_msgs/msg/PoseWithCovariance",
        include_str!("../ros2-msgs/geometry_msgs/msg/PoseWithCovariance.msg"),
    ),
    (
        "geometry_msgs/msg/Vector3",
        include_str!("../ros2-msgs/geometry_msgs/msg/Vector3.msg"),
    ),
    (
        "geometry_msgs/msg/Twist",
        include_str!("../ros2-msgs/geometry_msgs/msg/Twist.msg"),
    ),
    (
        "geometry_msgs/msg/TwistWithCovariance",
        include_str!("../ros2-msgs/geometry_msgs/msg/TwistWithCovariance.msg"),
    ),
    (
        "geometry_msgs/msg/Transform",
        include_str!("../ros2-msgs/geometry_msgs/msg/Transform.msg"),
    ),
    (
        "geometry_msgs/msg/TransformStamped",
        include_str!("../ros2-msgs/geometry_msgs/msg/TransformStamped.msg"),
    ),
    (
        "nav_msgs/msg/Odometry",
        include_str!("../ros2-msgs/nav_msgs/msg/Odometry.msg"),
    ),
    (
        "nav_msgs/msg/MapMetaData",
        include_str!("../ros2-msgs/nav_msgs/msg/MapMetaData.msg"),
    ),
    (
        "nav_msgs/msg/OccupancyGrid",
        include_str!("../ros2-msgs/nav_msgs/msg/OccupancyGrid.msg"),
    ),
    (
        "sensor_msgs/msg/CompressedImage",
        include_str!("../ros2-msgs/sensor_msgs/msg/CompressedImage.msg"),
    ),
    (
        "sensor_msgs/msg/RegionOfInterest",
        include_str!("../ros2-msgs/sensor_msgs/msg/RegionOfInterest.msg"),
    ),
    (
        "sensor_msgs/msg/CameraInfo",
        include_str!("../ros2-msgs/sensor_msgs/msg/CameraInfo.msg"),
    ),
    (
        "sensor_msgs/msg/LaserScan",
        include_str!("../ros2-msgs/sensor_msgs/msg/LaserScan.msg"),
    ),
    (
        "tf2_msgs/msg/TFMessage",
        include_str!("../ros2-msgs/tf2_msgs/msg/TFMessage.msg"),
    ),
];

/// A definition that is no `.msg` rosidl would take, or names a type
/// nobody vendored.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MsgError {
    #[error("{msg} line {line}: {why}")]
    Line {
        msg: String,
        line: usize,
        why: String,
    },
    #[error("{0} is not among the vendored message definitions")]
    Unknown(String),
}

/// A built-in type of the `.msg` language.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Primitive {
    Bool,
    Byte,
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

impl Primitive {
    fn named(name: &str) -> Option<Primitive> {
        Some(match name {
            "bool" => Primitive::Bool,
            "byte" => Primitive::Byte,
            "int8" => Primitive::Int8,
            // rosidl reads `char` as an unsigned byte.
            "uint8" | "char" => Primitive::UInt8,
            "int16" => Primitive::Int16,
            "uint16" => Primitive::UInt16,
            "int32" => Primitive::Int32,
            "uint32" => Primitive::UInt32,
            "int64" => Primitive::Int64,
            "uint64" => Primitive::UInt64,
            "float32" => Primitive::Float32,
            "float64" => Primitive::Float64,
            _ => return None,
        })
    }

    /// Its size on the wire, which is also its CDR alignment.
    #[cfg(test)]
    pub(crate) fn size(self) -> usize {
        match self {
            Primitive::Bool | Primitive::Byte | Primitive::Int8 | Primitive::UInt8 => 1,
            Primitive::Int16 | Primitive::UInt16 => 2,
            Primitive::Int32 | Primitive::UInt32 | Primitive::Float32 => 4,
            Primitive::Int64 | Primitive::UInt64 | Primitive::Float64 => 8,
        }
    }

    /// type_description_interfaces/FieldType's number.
    fn type_id(self) -> u8 {
        match self {
            Primitive::Int8 => 2,
            Primitive::UInt8 => 3,
            Primitive::Int16 => 4,
            Primitive::UInt16 => 5,
            Primitive::Int32 => 6,
            Primitive::UInt32 => 7,
            Primitive::Int64 => 8,
            Primitive::UInt64 => 9,
            Primitive::Float32 => 10,
            Primitive::Float64 => 11,
            Primitive::Bool => 15,
            Primitive::Byte => 16,
        }
    }
}

/// What one element of a field is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Element {
    Primitive(Primitive),
    /// A string, at most this many bytes when bounded.
    String(Option<u32>),
    /// Another message, by full type name.
    Nested(String),
}

/// One, a fixed number, or a sequence of elements.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Multiplicity {
    Single,
    Array(u32),
    Sequence(Option<u32>),
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Field {
    pub(crate) name: String,
    pub(crate) element: Element,
    pub(crate) shape: Multiplicity,
}

/// A message: its full type name and its fields (constants left out, as
/// they are from its type description).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct MsgDef {
    pub(crate) name: String,
    pub(crate) fields: Vec<Field>,
}

/// Reads the `.msg` text of type `name` (`package/msg/Type`).
pub(crate) fn parse(name: &str, text: &str) -> Result<MsgDef, MsgError> {
    let package = name.split('/').next().unwrap_or_default();
    let mut fields = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let bad = |why: String| MsgError::Line {
            msg: name.to_owned(),
            line: number + 1,
            why,
        };
        let line = line.split('#').next().unwrap_or_default().trim();
        let mut words = line.split_whitespace();
        let (Some(kind), rest) = (words.next(), words.next()) else {
            continue;
        };
        let Some(field) = rest else {
            return Err(bad(format!("'{line}' has a type and no name")));
        };
        // `TYPE NAME=VALUE` is a constant, `TYPE NAME VALUE` a default.
        if field.contains('=') || words.next() == Some("=") {
            continue;
        }
        if !field.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(bad(format!("'{field}' is no field name")));
        }
        let (base, shape) = shape_of(kind).map_err(bad)?;
        let element = element_of(base, package).map_err(bad)?;
        fields.push(Field {
            name: field.to_owned(),
            element,
            shape,
        });
    }
    Ok(MsgDef {
        name: name.to_owned(),
        fields,
    })
}

/// `T`, `T[N]`, `T[]` or `T[<=N]`.
fn shape_of(kind: &str) -> Result<(&str, Multiplicity), String> {
    let Some((base, bracket)) = kind.split_once('[') else {
        return Ok((kind, Multiplicity::Single));
    };
    let inside = bracket
        .strip_suffix(']')
        .ok_or_else(|| format!("'{kind}' opens a bracket it does not close"))?;
    let number = |n: &str| {
        n.parse::<u32>()
            .map_err(|_| format!("'{kind}': '{n}' is no size"))
    };
    let shape = match inside.strip_prefix("<=") {
        _ if inside.is_empty() => Multiplicity::Sequence(None),
        Some(bound) => Multiplicity::Sequence(Some(number(bound)?)),
        None => Multiplicity::Array(number(inside)?),
    };
    Ok((base, shape))
}

fn element_of(base: &str, package: &str) -> Result<Element, String> {
    if let Some(primitive) = Primitive::named(base) {
        return Ok(Element::Primitive(primitive));
    }
    if base == "string" {
        return Ok(Element::String(None));
    }
    if let Some(bound) = base.strip_prefix("string<=") {
        let bound = bound
            .parse()
            .map_err(|_| format!("'{base}': '{bound}' is no bound"))?;
        return Ok(Element::String(Some(bound)));
    }
    if base.starts_with("wstring") || base == "wchar" {
        return Err(format!("'{base}': wide strings are not supported"));
    }
    let nested = match base.split('/').collect::<Vec<_>>()[..] {
        ["Header"] => "std_msgs/msg/Header".to_owned(),
        [name] => format!("{package}/msg/{name}"),
        [other, name] => format!("{other}/msg/{name}"),
        _ => return Err(format!("'{base}' is no type")),
    };
    Ok(Element::Nested(nested))
}

/// The vendored messages, read once.
#[derive(Debug, Clone)]
pub(crate) struct MessageDefinitions {
    defs: BTreeMap<String, MsgDef>,
}

impl MessageDefinitions {
    pub(crate) fn vendored() -> Result<MessageDefinitions, MsgError> {
        let mut defs = BTreeMap::new();
        for (name, text) in VENDORED {
            defs.insert((*name).to_owned(), parse(name, text)?);
        }
        Ok(MessageDefinitions { defs })
    }

    pub(crate) fn get(&self, name: &str) -> Result<&MsgDef, MsgError> {
        self.defs
            .get(name)
            .ok_or_else(|| MsgError::Unknown(name.to_owned()))
    }

    /// `name` and every message it holds, however deep.
    fn closure(&self, name: &str) -> Result<BTreeSet<String>, MsgError> {
        let mut seen = BTreeSet::new();
        let mut to_visit = vec![name.to_owned()];
        while let Some(next) = to_visit.pop() {
            for field in &self.get(&next)?.fields {
                if let Element::Nested(inner) = &field.element
                    && seen.insert(inner.clone())
                {
                    to_visit.push(inner.clone());
                }
            }
        }
        Ok(seen)
    }

    /// The RIHS01 hash of message `name`, as rmw_zenoh puts it in key
    /// expressions: `RIHS01_` and 64 hex digits.
    pub(crate) fn type_hash(&self, name: &str) -> Result<String, MsgError> {
        let mut json = String::from("{\"type_description\": ");
        describe(&mut json, self.get(name)?);
        json.push_str(", \"referenced_type_descriptions\": [");
        for (i, inner) in self.closure(name)?.iter().enumerate() {
            if i > 0 {
                json.push_str(", ");
            }
            describe(&mut json, self.get(inner)?);
        }
        json.push_str("]}");
        let digest = Sha256::digest(json.as_bytes());
        let mut hash = String::from("RIHS01_");
        for byte in digest {
            let _ = write!(hash, "{byte:02x}");
        }
        Ok(hash)
    }
}

/// A type description as REP 2011 hashes it: Python's `json.dumps` with
/// `", "` and `": "` between items, default values left out, and a
/// message without fields given rosidl's one placeholder byte.
fn describe(json: &mut String, def: &MsgDef) {
    let quoted = |s: &str| serde_json::to_string(s).unwrap_or_default();
    let _ = write!(
        json,
        "{{\"type_name\": {}, \"fields\": [",
        quoted(&def.name)
    );
    let placeholder = [Field {
        name: "structure_needs_at_least_one_member".into(),
        element: Element::Primitive(Primitive::UInt8),
        shape: Multiplicity::Single,
    }];
    let fields = if def.fields.is_empty() {
        &placeholder[..]
    } else {
        &def.fields[..]
    };
    for (i, field) in fields.iter().enumerate() {
        if i > 0 {
            json.push_str(", ");
        }
        let (element_id, string_capacity, nested) = match &field.element {
            Element::Primitive(p) => (p.type_id(), 0, ""),
            Element::String(None) => (17, 0, ""),
            Element::String(Some(bound)) => (21, *bound, ""),
            Element::Nested(name) => (1, 0, name.as_str()),
        };
        let (offset, capacity) = match field.shape {
            Multiplicity::Single => (0, 0),
            Multiplicity::Array(n) => (48, n),
            Multiplicity::Sequence(Some(n)) => (96, n),
            Multiplicity::Sequence(None) => (144, 0),
        };
        let _ = write!(
            json,
            "{{\"name\": {}, \"type\": {{\"type_id\": {}, \"capacity\": {capacity}, \
             \"string_capacity\": {string_capacity}, \"nested_type_name\": {}}}}}",
            quoted(&field.name),
            u16::from(element_id) + offset,
            quoted(nested),
        );
    }
    json.push_str("]}");
}

/// The DDS name rmw_zenoh gives type `package/msg/Type` in key expressions.
pub(crate) fn dds_name(name: &str) -> String {
    let mut parts = name.splitn(3, '/');
    let (package, kind, leaf) = (
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
    );
    format!("{package}::{kind}::dds_::{leaf}_")
}
