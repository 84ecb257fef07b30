//! The ROS 2 wire, held to the vendored definitions: every message the
//! lab encodes is walked field by field as its `.msg` says (and copied by
//! that walk to the same bytes), decodes to itself, and any bytes decode
//! or fail without a panic; the type hashes are ROS's own.

use proptest::prelude::*;

use super::cdr::{CdrError, Reader, Writer};
use super::graph::{Origin, Qos, attachment};
use super::messages::*;
use super::msg::{Element, MessageDefinitions, MsgDef, Multiplicity, Primitive, parse};

/// Reads one value of `def` from `r` by the definition alone, writing the
/// same to `w`.
fn walk(
    catalogue: &MessageDefinitions,
    def: &MsgDef,
    r: &mut Reader<'_>,
    w: &mut Writer,
) -> Result<(), CdrError> {
    for field in &def.fields {
        let n = match field.shape {
            Multiplicity::Single => 1,
            Multiplicity::Array(n) => n as usize,
            Multiplicity::Sequence(_) => {
                let n = r.count(1, "sequence")?;
                w.count(n);
                n
            }
        };
        for _ in 0..n {
            element(catalogue, &field.element, r, w)?;
        }
    }
    Ok(())
}

fn element(
    catalogue: &MessageDefinitions,
    element: &Element,
    r: &mut Reader<'_>,
    w: &mut Writer,
) -> Result<(), CdrError> {
    match element {
        // Copied as bits: a double's bytes carry any 8-byte value unchanged.
        Element::Primitive(p) => match p.size() {
            1 => w.i8(r.i8("byte")?),
            4 if *p == Primitive::Float32 => w.f32(r.f32("float")?),
            4 => w.u32(r.u32("word")?),
            8 => w.f64(r.f64("double")?),
            _ => panic!("no vendored message has 16-bit fields"),
        },
        Element::String(_) => w.string(&r.string("string")?),
        Element::Nested(name) => {
            let inner = catalogue.get(name).expect("vendored");
            walk(catalogue, inner, r, w)?;
        }
    }
    Ok(())
}

/// `message` walked by its definition: the same bytes, all of them.
fn walked<M: Message>(message: &M) -> Result<Vec<u8>, CdrError> {
    let catalogue = MessageDefinitions::vendored().expect("the vendored definitions parse");
    let bytes = message.encode();
    let mut r = Reader::new(&bytes)?;
    let mut w = Writer::new();
    walk(
        &catalogue,
        catalogue.get(M::TYPE).expect("vendored"),
        &mut r,
        &mut w,
    )?;
    r.end()?;
    Ok(w.finish())
}

fn check<M: Message + PartialEq + std::fmt::Debug>(message: &M) -> Result<(), TestCaseError> {
    let bytes = message.encode();
    prop_assert_eq!(
        walked(message).map_err(|e| TestCaseError::fail(e.to_string()))?,
        bytes.clone()
    );
    prop_assert_eq!(
        &M::decode(&bytes).map_err(|e| TestCaseError::fail(e.to_string()))?,
        message
    );
    Ok(())
}

fn number() -> impl Strategy<Value = f64> {
    -1e6..1e6
}

fn text() -> impl Strategy<Value = String> {
    "[a-z_/é]{0,12}"
}

prop_compose! {
    fn time()(sec in any::<i32>(), nanosec in 0u32..1_000_000_000) -> Time {
        Time { sec, nanosec }
    }
}

prop_compose! {
    fn header()(stamp in time(), frame_id in text()) -> Header {
        Header { stamp, frame_id }
    }
}

prop_compose! {
    fn vector()(x in number(), y in number(), z in number()) -> Vector3 {
        Vector3 { x, y, z }
    }
}

prop_compose! {
    fn quaternion()(theta in -10.0..10.0f64) -> Quaternion {
        Quaternion::about_z(theta)
    }
}

prop_compose! {
    fn pose()(position in vector(), orientation in quaternion()) -> Pose {
        Pose { position, orientation }
    }
}

prop_compose! {
    fn twist()(linear in vector(), angular in vector()) -> Twist {
        Twist { linear, angular }
    }
}

prop_compose! {
    fn transform()(header in header(), child_frame_id in text(), translation in vector(), rotation in quaternion()) -> TransformStamped {
        TransformStamped { header, child_frame_id, translation, rotation }
    }
}

proptest! {
    #[test]
    fn twists_follow_their_definition(message in twist()) {
        check(&message)?;
    }

    #[test]
    fn odometry_follows_its_definition(
        header in header(), child in text(), pose in pose(), twist in twist(),
        covariance in proptest::array::uniform32(number()), last in number(),
    ) {
        let mut pose_covariance = [0.0; 36];
        pose_covariance[..32].copy_from_slice(&covariance);
        pose_covariance[35] = last;
        let message = Odometry {
            header, child_frame_id: child, pose, pose_covariance, twist,
            twist_covariance: pose_covariance,
        };
        check(&message)?;
    }

    #[test]
    fn transforms_follow_their_definition(transforms in proptest::collection::vec(transform(), 0..5)) {
        check(&TfMessage { transforms })?;
    }

    #[test]
    fn images_and_camera_info_follow_their_definitions(
        header in header(), format in text(), data in proptest::collection::vec(any::<u8>(), 0..64),
        d in proptest::collection::vec(number(), 0..6), k in proptest::array::uniform9(number()),
        size in (1u32..5000, 1u32..5000),
    ) {
        check(&CompressedImage { header: header.clone(), format, data })?;
        let mut p = [0.0; 12];
        p[..9].copy_from_slice(&k);
        check(&CameraInfo {
            header, height: size.1, width: size.0, distortion_model: "plumb_bob".into(),
            d, k, r: k, p,
        })?;
    }

    #[test]
    fn scans_and_maps_follow_their_definitions(
        header in header(), ranges in proptest::collection::vec(-1e3f32..1e3, 0..40),
        angles in proptest::array::uniform7(-10f32..10.0),
        data in proptest::collection::vec(any::<i8>(), 0..200), origin in pose(), load in time(),
        size in (0u32..100, 0u32..100), resolution in 0.001f32..1.0,
    ) {
        let [angle_min, angle_max, angle_increment, time_increment, scan_time, range_min, range_max] = angles;
        check(&LaserScan {
            header: header.clone(), angle_min, angle_max, angle_increment, time_increment, scan_time,
            range_min, range_max, intensities: ranges.iter().map(|r| r.abs()).collect(), ranges,
        })?;
        check(&OccupancyGrid {
            header, map_load_time: load, resolution, width: size.0, height: size.1, origin, data,
        })?;
    }

    /// Bytes off the network decode or are refused, never a panic, and a
    /// count larger than the bytes left is refused before anything is kept.
    #[test]
    fn any_bytes_decode_or_fail_cleanly(mut bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let _ = Twist::decode(&bytes);
        let _ = Odometry::decode(&bytes);
        let _ = TfMessage::decode(&bytes);
        if bytes.len() >= 4 {
            bytes[..4].copy_from_slice(&[0, 1, 0, 0]);
        }
        let _ = CompressedImage::decode(&bytes);
        let _ = CameraInfo::decode(&bytes);
        let _ = LaserScan::decode(&bytes);
        let _ = OccupancyGrid::decode(&bytes);
    }
}

/// ROS 2's own type hashes (as `ros2 topic info -v` prints them on
/// Jazzy) for types whose definitions have not changed since.
#[test]
fn type_hashes_are_ros_s() {
    let catalogue = MessageDefinitions::vendored().expect("the vendored definitions parse");
    assert_eq!(
        catalogue
            .type_hash("geometry_msgs/msg/Twist")
            .expect("vendored"),
        "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"
    );
    // Every vendored message names only messages that are vendored too.
    for name in [
        "nav_msgs/msg/Odometry",
        "tf2_msgs/msg/TFMessage",
        "sensor_msgs/msg/CameraInfo",
        "nav_msgs/msg/OccupancyGrid",
    ] {
        let hash = catalogue.type_hash(name).expect("vendored");
        assert_eq!(hash.len(), 7 + 64, "{name}: {hash}");
    }
}

#[test]
fn definitions_are_read_as_rosidl_reads_them() {
    let def = parse(
        "pkg/msg/Sample",
        "# a comment\nint32 A_CONSTANT=3\nstring<=8 name  # trailing\nfloat64[9] k\nuint8[] data\nHeader header\nOther[<=4] others\nbool flag false\n",
    )
    .expect("parses");
    let shapes: Vec<(&str, &Multiplicity)> = def
        .fields
        .iter()
        .map(|f| (f.name.as_str(), &f.shape))
        .collect();
    assert_eq!(
        shapes,
        [
            ("name", &Multiplicity::Single),
            ("k", &Multiplicity::Array(9)),
            ("data", &Multiplicity::Sequence(None)),
            ("header", &Multiplicity::Single),
            ("others", &Multiplicity::Sequence(Some(4))),
            ("flag", &Multiplicity::Single),
        ]
    );
    assert_eq!(def.fields[0].element, Element::String(Some(8)));
    assert_eq!(
        def.fields[3].element,
        Element::Nested("std_msgs/msg/Header".into())
    );
    assert_eq!(
        def.fields[4].element,
        Element::Nested("pkg/msg/Other".into())
    );
    let bad = parse("pkg/msg/Bad", "float64[ k\n").expect_err("an unclosed bracket");
    assert!(bad.to_string().contains("pkg/msg/Bad line 1"), "{bad}");
}

#[test]
fn attachments_and_qos_are_rmw_zenoh_s() {
    let gid = [7u8; 16];
    let bytes = attachment(5, 1_700_000_000_000_000_000, &gid);
    assert_eq!(bytes.len(), 33);
    assert_eq!(&bytes[..8], &5i64.to_le_bytes());
    assert_eq!(&bytes[8..16], &1_700_000_000_000_000_000i64.to_le_bytes());
    assert_eq!(bytes[16], 16);
    assert_eq!(&bytes[17..], &gid);
    let origin = Origin::of(&bytes).unwrap();
    assert_eq!((origin.sequence, origin.gid.as_slice()), (5, &gid[..]));
    assert_eq!(Origin::of(&bytes[..20]), None, "cut short");
    assert_eq!(Origin::of(&[]), None);
    assert_eq!(Qos::LATCHED.token_chunk(), "1:1:1,1:,:,:,,");
    assert_eq!(Qos::SENSOR.token_chunk(), "2:2:1,5:,:,:,,");
}

proptest! {
    /// Any bytes as an attachment: an origin or none, never a panic; one
    /// written as rmw_zenoh writes it reads back.
    #[test]
    fn attachments_read_back(bytes in proptest::collection::vec(any::<u8>(), 0..64),
                             sequence in any::<i64>(), gid in proptest::array::uniform16(any::<u8>())) {
        let _ = Origin::of(&bytes);
        let origin = Origin::of(&attachment(sequence, 0, &gid)).unwrap();
        prop_assert_eq!((origin.sequence, origin.gid), (sequence, gid.to_vec()));
    }
}
