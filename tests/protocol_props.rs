//! Property tests of protocol v1's wire form: every message survives
//! encode → decode unchanged, and no input, however malformed, makes the
//! decoder panic.

use proptest::prelude::*;
use serde_json::{Value, json};
use vl_core::{
    Arena, CameraModel, Definition, Drive, EndReason, ErrorCode, ErrorMm, Experiment, Feedback,
    Goal, GuestMessage, HostMessage, Material, MountedLab, Obstacle, PathAnalysis, Point, Pose,
    PoseSource, RobotModel, Role, Secret, SensorMount, Shape, SpeedResponse, Stopper, Summary,
    WheelSpeeds, Wire,
};

fn num() -> impl Strategy<Value = f64> {
    prop_oneof![-1e6f64..1e6, Just(0.0), any::<i32>().prop_map(f64::from)]
}

fn text() -> impl Strategy<Value = String> {
    "[ -~é→ω]{0,16}"
}

fn point() -> impl Strategy<Value = Point> {
    (num(), num()).prop_map(|(x_mm, y_mm)| Point { x_mm, y_mm })
}

fn pose() -> impl Strategy<Value = Pose> {
    (num(), num(), num()).prop_map(|(x_mm, y_mm, theta_rad)| Pose {
        x_mm,
        y_mm,
        theta_rad,
    })
}

fn wheels() -> impl Strategy<Value = WheelSpeeds> {
    (num(), num()).prop_map(|(left_mm_s, right_mm_s)| WheelSpeeds {
        left_mm_s,
        right_mm_s,
    })
}

fn material() -> impl Strategy<Value = Material> {
    (num(), any::<[u8; 3]>()).prop_map(|(reflectivity, colour)| Material {
        reflectivity,
        colour,
    })
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        (num(), num(), num(), num()).prop_map(|(x_mm, y_mm, width_mm, height_mm)| Shape::Rect {
            x_mm,
            y_mm,
            width_mm,
            height_mm
        }),
        (num(), num(), num()).prop_map(|(x_mm, y_mm, radius_mm)| Shape::Circle {
            x_mm,
            y_mm,
            radius_mm
        }),
        proptest::collection::vec(point(), 0..6).prop_map(|points| Shape::Polygon { points }),
    ]
}

fn goal() -> impl Strategy<Value = Goal> {
    (num(), num(), num()).prop_map(|(x_mm, y_mm, tolerance_mm)| Goal {
        x_mm,
        y_mm,
        tolerance_mm,
    })
}

// The composite strategies are boxed: nested unboxed, their types outgrow a
// debug test thread's stack.
fn definition() -> BoxedStrategy<Definition> {
    (
        proptest::option::of(goal()),
        (
            proptest::collection::vec(point(), 0..4),
            proptest::collection::vec(point(), 0..3),
        ),
        proptest::collection::vec(shape(), 0..3),
        proptest::option::of(num()),
        proptest::option::of(num()),
        (
            proptest::option::of(num()),
            proptest::option::of(any::<[u8; 32]>().prop_map(vl_core::ModuleHash)),
        ),
    )
        .prop_map(
            |(
                goal,
                (path, waypoints),
                virtual_obstacles,
                max_speed_mm_s,
                time_limit_s,
                (lookahead_mm, controller),
            )| {
                Definition {
                    goal,
                    path,
                    waypoints,
                    virtual_obstacles,
                    max_speed_mm_s,
                    time_limit_s,
                    lookahead_mm,
                    controller,
                }
            },
        )
        .boxed()
}

fn arena() -> BoxedStrategy<Arena> {
    (
        text(),
        num(),
        num(),
        proptest::collection::vec((shape(), material()), 0..4),
        material(),
        pose(),
        proptest::option::of(point()),
    )
        .prop_map(
            |(name, width_mm, height_mm, obstacles, walls, start, goal)| Arena {
                name,
                width_mm,
                height_mm,
                obstacles: obstacles
                    .into_iter()
                    .map(|(shape, material)| Obstacle { shape, material })
                    .collect(),
                walls,
                start,
                goal,
            },
        )
        .boxed()
}

fn robot() -> BoxedStrategy<RobotModel> {
    (
        text(),
        num(),
        num(),
        num(),
        num(),
        num(),
        proptest::collection::vec((num(), num(), num()), 0..9),
        (num(), num(), num(), num()),
    )
        .prop_map(
            |(
                name,
                radius_mm,
                wheel_base_mm,
                mm_per_pulse,
                max_wheel_speed_mm_s,
                sensor_range_mm,
                sensors,
                (gain, time_constant_s, max_accel_mm_s2, dead_time_s),
            )| {
                RobotModel {
                    name,
                    radius_mm,
                    wheel_base_mm,
                    mm_per_pulse,
                    max_wheel_speed_mm_s,
                    sensor_range_mm,
                    wheel_slip: vl_core::KHEPERA_WHEEL_SLIP,
                    sensors: sensors
                        .into_iter()
                        .map(|(x_mm, y_mm, angle_rad)| SensorMount {
                            x_mm,
                            y_mm,
                            angle_rad,
                        })
                        .collect(),
                    response: SpeedResponse {
                        gain,
                        time_constant_s,
                        max_accel_mm_s2,
                        dead_time_s,
                    },
                }
            },
        )
        .boxed()
}

fn camera() -> BoxedStrategy<CameraModel> {
    (
        1u32..4000,
        1u32..4000,
        100.0f64..4000.0,
        0.0f64..120.0,
        -0.7f64..0.7,
    )
        .prop_map(|(width_px, height_px, width_mm, fps, tilt)| {
            CameraModel::tilted(width_mm, 0.75 * width_mm, width_px, height_px, tilt, fps)
                .expect("within ±0.7 rad the camera sees the floor")
        })
        .boxed()
}

fn role() -> impl Strategy<Value = Role> {
    prop_oneof![Just(Role::Operator), Just(Role::Observer)]
}

fn drive() -> impl Strategy<Value = Drive> {
    prop_oneof![
        (num(), num()).prop_map(|(left, right)| Drive::Wheels { left, right }),
        (num(), num()).prop_map(|(v, w)| Drive::Velocity { v, w }),
    ]
}

fn error_code() -> impl Strategy<Value = ErrorCode> {
    proptest::sample::select(<ErrorCode as strum::VariantArray>::VARIANTS)
}

fn summary() -> BoxedStrategy<Summary> {
    (
        proptest::sample::select(<EndReason as strum::VariantArray>::VARIANTS),
        any::<bool>(),
        any::<u64>(),
        pose(),
        (num(), num()),
        (any::<u64>(), any::<u64>(), any::<u64>()),
        proptest::option::of(
            (any::<bool>(), any::<u64>()).prop_map(|(operator, session)| Stopper {
                role: if operator {
                    Role::Operator
                } else {
                    Role::Observer
                },
                session,
            }),
        ),
        (
            proptest::option::of(num()),
            proptest::option::of(num()),
            pose_source(),
            proptest::option::of(path_analysis()),
        ),
        (
            proptest::option::of((num(), num(), any::<bool>(), num()).prop_map(
                |(uncertain_mm, passes_mm, wall, margin_mm)| vl_core::HeldBack {
                    uncertain_mm,
                    passes_mm,
                    wall,
                    margin_mm,
                },
            )),
            proptest::option::of(gap()),
            proptest::option::of(recording_note()),
        ),
    )
        .prop_map(
            |(
                reason,
                reached_goal,
                events,
                final_pose,
                (seconds, distance_mm),
                (collisions, max_event_gap, sync_violations),
                stopped_by,
                (closest_mm, speed_kept, pose_source, path),
                (held_back, forecast, recording),
            )| {
                Summary {
                    experiment: None,
                    reason,
                    reached_goal,
                    events,
                    final_pose,
                    seconds,
                    distance_mm,
                    collisions,
                    closest_mm,
                    speed_kept,
                    pose_source,
                    path,
                    max_event_gap,
                    sync_violations,
                    stopped_by,
                    held_back,
                    fault: None,
                    forecast,
                    recording,
                    waypoints: (events % 3 == 0).then_some(vl_core::WaypointsVisited {
                        visited: (events % 5) as usize,
                        of: 5,
                    }),
                }
            },
        )
        .boxed()
}

fn closest() -> impl Strategy<Value = vl_core::Closest> {
    let to = prop_oneof![
        Just(vl_core::Nearest::Wall),
        (0..9usize).prop_map(vl_core::Nearest::Obstacle),
        (0..9usize).prop_map(vl_core::Nearest::VirtualObstacle),
    ];
    (num(), point(), to).prop_map(|(mm, at, to)| vl_core::Closest { mm, at, to })
}

/// A forecast of one or two seeds, judged by some limits.
fn verdict() -> impl Strategy<Value = vl_core::ForecastVerdict> {
    let run = (
        (any::<u64>(), any::<bool>(), num(), closest(), closest()),
        (
            any::<u32>(),
            proptest::option::of(point()),
            num(),
            num(),
            num(),
        ),
        proptest::collection::vec(point(), 0..5),
        proptest::option::of("[a-z ]{0,20}"),
    )
        .prop_map(
            |(
                (seed, reached_goal, seconds, closest, end),
                (collisions, first_contact, held_back_s, saturated_s, mean_error_mm),
                path,
                fault,
            )| vl_core::SeedRun {
                seed,
                reached_goal,
                seconds,
                closest,
                end,
                collisions: u64::from(collisions),
                first_contact,
                held_back_s,
                saturated_s,
                mean_error_mm,
                path,
                fault,
            },
        );
    let limits =
        (num(), proptest::option::of(num())).prop_map(|(min_clearance_mm, max_seconds)| {
            vl_core::ForecastLimits {
                min_clearance_mm,
                max_seconds,
            }
        });
    (proptest::collection::vec(run, 1..3), num(), limits).prop_map(
        |(runs, path_every_s, limits)| {
            vl_core::ForecastVerdict::new(vl_core::Forecast { runs, path_every_s }, limits)
        },
    )
}

fn gap() -> impl Strategy<Value = vl_core::Gap> {
    (
        proptest::option::of(num()),
        (num(), num(), num()),
        proptest::option::of(num()),
        proptest::option::of(num()),
    )
        .prop_map(
            |(
                forecast_s,
                (run_s, path_mean_mm, path_max_mm),
                forecast_closest_mm,
                run_closest_mm,
            )| {
                vl_core::Gap {
                    forecast_s,
                    run_s,
                    path_mean_mm,
                    path_max_mm,
                    forecast_closest_mm,
                    run_closest_mm,
                }
            },
        )
}

fn pose_source() -> impl Strategy<Value = PoseSource> {
    proptest::sample::select(vec![PoseSource::Camera, PoseSource::Odometry])
}

fn error_mm() -> impl Strategy<Value = ErrorMm> {
    (num(), num(), num()).prop_map(|(mean, max, rms)| ErrorMm { mean, max, rms })
}

fn path_analysis() -> BoxedStrategy<PathAnalysis> {
    (
        proptest::collection::vec(point(), 0..6),
        proptest::collection::vec(point(), 0..6),
        proptest::option::of(error_mm()),
        proptest::option::of(error_mm()),
        proptest::option::of(error_mm()),
    )
        .prop_map(
            |(estimated, truth, tracking_error_mm, path_error_mm, estimate_error_mm)| {
                PathAnalysis {
                    estimated,
                    truth,
                    tracking_error_mm,
                    path_error_mm,
                    estimate_error_mm,
                }
            },
        )
        .boxed()
}

fn guest_message() -> impl Strategy<Value = GuestMessage> {
    prop_oneof![
        (
            any::<u32>(),
            role(),
            proptest::option::of(text()),
            proptest::option::of(text())
        )
            .prop_map(|(protocol, role, token, resume)| {
                GuestMessage::Hello {
                    protocol,
                    role,
                    token: token.clone(),
                    resume,
                    user: token.clone(),
                    password: token.clone().map(Secret),
                    session: token.map(Secret),
                }
            }),
        num().prop_map(|t| GuestMessage::Ping { t }),
        num().prop_map(|t| GuestMessage::Pong { t }),
        text().prop_map(|experiment| GuestMessage::Mount { experiment }),
        definition().prop_map(|definition| GuestMessage::Define { definition }),
        Just(GuestMessage::Start),
        Just(GuestMessage::Stop),
        Just(GuestMessage::Reset),
        Just(GuestMessage::EmergencyStop),
        (any::<u64>(), proptest::option::of(any::<u64>()), drive())
            .prop_map(|(event, seen, drive)| GuestMessage::Command { event, seen, drive }),
        Just(GuestMessage::Recordings),
        (recording_name(), any::<u64>())
            .prop_map(|(name, offset)| GuestMessage::Download { name, offset }),
        Just(GuestMessage::Bye),
    ]
}

fn recording_name() -> impl Strategy<Value = vl_core::RecordingName> {
    (any::<u64>(), any::<u64>()).prop_map(|(ms, run)| vl_core::RecordingName::of_run(ms, run))
}

fn recording_note() -> impl Strategy<Value = vl_core::RecordingNote> {
    (
        recording_name(),
        any::<u64>(),
        proptest::option::of(".{0,40}"),
    )
        .prop_map(|(name, dropped_frames, stopped)| vl_core::RecordingNote {
            name,
            dropped_frames,
            stopped,
        })
}

fn experiment() -> impl Strategy<Value = Experiment> {
    let shipped: Vec<Experiment> = vl_core::Experiments::shipped()
        .experiments()
        .cloned()
        .collect();
    proptest::sample::select(shipped)
}

fn scene() -> impl Strategy<Value = vl_core::LabScene> {
    (arena(), robot(), camera()).prop_map(|(arena, robot, camera)| vl_core::LabScene {
        arena,
        robot,
        camera,
    })
}

fn host_message() -> impl Strategy<Value = HostMessage> {
    let info = (experiment(), text()).prop_map(|(experiment, title)| Experiment {
        title,
        help: experiment.title.clone(),
        ..experiment
    });
    prop_oneof![
        (
            any::<u64>(),
            role(),
            proptest::collection::vec(info, 0..3),
            proptest::option::of(text()),
            proptest::option::of(scene()),
        )
            .prop_map(
                |(session, role, experiments, resume, scene)| HostMessage::Welcome {
                    session,
                    role,
                    experiments,
                    user: resume.clone(),
                    resume,
                    scene: scene.map(Box::new),
                }
            ),
        (error_code(), text()).prop_map(|(code, message)| HostMessage::Error { code, message }),
        num().prop_map(|t| HostMessage::Ping { t }),
        num().prop_map(|t| HostMessage::Pong { t }),
        (experiment(), scene()).prop_map(|(experiment, scene)| {
            HostMessage::Mounted(Box::new(MountedLab {
                experiment: experiment.id,
                scene,
            }))
        }),
        definition().prop_map(|definition| HostMessage::Defined { definition }),
        verdict().prop_map(|v| HostMessage::Forecast(Box::new(v))),
        any::<u64>().prop_map(|event| HostMessage::Started { event }),
        (
            any::<u64>(),
            num(),
            pose(),
            wheels(),
            proptest::collection::vec(any::<u16>(), 0..9),
            any::<bool>(),
            proptest::option::of((num(), num())),
            (any::<bool>(), pose_source()),
        )
            .prop_map(
                |(event, t_ms, pose, wheels, proximity, contact, force, (limited, source))| {
                    HostMessage::Feedback(Feedback {
                        event,
                        t_ms,
                        pose,
                        wheels,
                        proximity,
                        contact,
                        force: force.map(|(x, y)| [x, y]),
                        limited,
                        source,
                    })
                },
            ),
        summary().prop_map(|summary| HostMessage::Done {
            summary: Box::new(summary)
        }),
        Just(HostMessage::Bye),
    ]
}

/// Arbitrary JSON, often shaped like a message: an object with a known
/// `type` and fields of any kind.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        num().prop_map(Value::from),
        text().prop_map(Value::from),
    ];
    leaf.prop_recursive(4, 32, 6, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            proptest::collection::btree_map(
                prop_oneof![
                    text(),
                    proptest::sample::select(vec![
                        "type".to_owned(),
                        "event".into(),
                        "left".into(),
                        "v".into(),
                        "goal".into(),
                        "role".into(),
                        "protocol".into(),
                        "pose".into(),
                        "summary".into(),
                    ]),
                ],
                inner,
                0..6
            )
            .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn guest_messages_round_trip(message in guest_message()) {
        let wire = message.encode();
        prop_assert_eq!(GuestMessage::decode(&wire), Ok(message));
    }

    #[test]
    fn host_messages_round_trip(message in host_message()) {
        let wire = message.encode();
        prop_assert_eq!(HostMessage::decode(&wire), Ok(message));
    }

    #[test]
    fn decoding_arbitrary_text_never_panics(text in any::<String>()) {
        let _ = GuestMessage::decode(&text);
        let _ = HostMessage::decode(&text);
    }

    #[test]
    fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = GuestMessage::decode(&text);
        let _ = HostMessage::decode(&text);
        let _ = vl_core::FrameHeader::decode(&bytes);
    }

    #[test]
    fn decoding_arbitrary_json_never_panics(
        mut value in json_value(),
        kind in proptest::sample::select(
            GuestMessage::TYPES.iter().chain(HostMessage::TYPES).copied().collect::<Vec<_>>()
        ),
        typed in any::<bool>(),
    ) {
        if typed && let Value::Object(map) = &mut value {
            map.insert("type".into(), json!(kind));
        }
        let text = value.to_string();
        let guest = GuestMessage::decode(&text);
        let host = HostMessage::decode(&text);
        // Whatever was decoded re-encodes and decodes to itself.
        if let Ok(m) = guest { prop_assert_eq!(GuestMessage::decode(&m.encode()), Ok(m)); }
        if let Ok(m) = host { prop_assert_eq!(HostMessage::decode(&m.encode()), Ok(m)); }
    }
}
