//! Planning against brute force on random maps: a path exists exactly when
//! a naive flood fill connects start and goal, NF1 is the breadth-first
//! distance, the descent goes down one value per step to the goal, the
//! smooth path stays in free cells, and its clearance is what an exhaustive
//! search over every blocked cell says.

use std::collections::VecDeque;

use proptest::prelude::*;
use vl_core::{
    CSpace, CSpaceCell, Connectivity, Footprint, Grid, Nf1, NoPath, Plan, Point, Pose, clearance,
    plan,
};

const CELL_MM: f64 = 10.0;

fn random_map() -> impl Strategy<Value = Grid> {
    (3u32..18, 3u32..18, 0.0f64..0.45).prop_flat_map(|(w, h, density)| {
        proptest::collection::vec(proptest::bool::weighted(density), (w * h) as usize).prop_map(
            move |blocked| Grid {
                width: w,
                height: h,
                cell_mm: CELL_MM,
                blocked,
            },
        )
    })
}

fn connectivity() -> impl Strategy<Value = Connectivity> {
    prop_oneof![Just(Connectivity::Four), Just(Connectivity::Eight)]
}

/// A pose anywhere on the map (fractions of its extent); when `snap`, moved
/// on to the next free cell in raster order, if there is one, so most cases
/// plan rather than stop at a blocked start or goal.
fn pose_on(cs: &CSpace, (fx, fy, theta): (f64, f64, f64), snap: bool) -> Pose {
    let grid = cs.grid();
    let (w, h) = grid.size_mm();
    let pose = Pose {
        x_mm: fx * w,
        y_mm: fy * h,
        theta_rad: theta,
    };
    let blocked = &cs.slices[cs.slice_of(theta)].blocked;
    let (c, r) = grid.cell_of(pose.point()).unwrap();
    let here = grid.index(c, r);
    let Some(i) = (0..blocked.len())
        .map(|k| (here + k) % blocked.len())
        .find(|&i| !blocked[i])
    else {
        return pose;
    };
    if !snap || i == here {
        return pose;
    }
    let centre = grid.centre(i as u32 % grid.width, i as u32 / grid.width);
    let offset = |f: f64, size: f64| (f * size / grid.cell_mm).fract() - 0.5;
    Pose {
        x_mm: centre.x_mm + offset(fx, w) * grid.cell_mm,
        y_mm: centre.y_mm + offset(fy, h) * grid.cell_mm,
        theta_rad: theta,
    }
}

/// Cells one step from `cell`, by the rules the planner states, found by
/// looking at every cell of the C-space.
fn steps(cs: &CSpace, conn: Connectivity, (c, r, k): CSpaceCell) -> Vec<CSpaceCell> {
    let n = cs.slices.len() as u32;
    let free = |c: i64, r: i64, k: u32| {
        let g = &cs.slices[k as usize];
        c >= 0
            && r >= 0
            && c < i64::from(g.width)
            && r < i64::from(g.height)
            && !g.is_blocked(c as u32, r as u32)
    };
    let mut out = Vec::new();
    let (ci, ri) = (i64::from(c), i64::from(r));
    for dr in -1i64..=1 {
        for dc in -1i64..=1 {
            let diagonal = dc != 0 && dr != 0;
            let allowed = match (dc, dr) {
                (0, 0) => false,
                _ if diagonal => {
                    conn == Connectivity::Eight && free(ci + dc, ri, k) && free(ci, ri + dr, k)
                }
                _ => true,
            };
            if allowed && free(ci + dc, ri + dr, k) {
                out.push(((ci + dc) as u32, (ri + dr) as u32, k));
            }
        }
    }
    if n > 1 {
        for kk in [(k + 1) % n, (k + n - 1) % n] {
            if free(ci, ri, kk) && !out.contains(&(c, r, kk)) {
                out.push((c, r, kk));
            }
        }
    }
    out
}

/// Breadth-first distances from `from` over free cells, as a map.
fn bfs(
    cs: &CSpace,
    conn: Connectivity,
    from: CSpaceCell,
) -> std::collections::HashMap<CSpaceCell, u32> {
    let mut dist = std::collections::HashMap::from([(from, 0)]);
    let mut queue = VecDeque::from([from]);
    while let Some(cell) = queue.pop_front() {
        let d = dist[&cell];
        for next in steps(cs, conn, cell) {
            dist.entry(next).or_insert_with(|| {
                queue.push_back(next);
                d + 1
            });
        }
    }
    dist
}

/// Whether a depth-first flood fill from `from` meets `to`.
fn flood_connected(cs: &CSpace, conn: Connectivity, from: CSpaceCell, to: CSpaceCell) -> bool {
    let mut seen = std::collections::HashSet::from([from]);
    let mut stack = vec![from];
    while let Some(cell) = stack.pop() {
        if cell == to {
            return true;
        }
        for next in steps(cs, conn, cell) {
            if seen.insert(next) {
                stack.push(next);
            }
        }
    }
    false
}

fn cell_of(cs: &CSpace, pose: Pose) -> Option<CSpaceCell> {
    let (c, r) = cs.grid().cell_of(pose.point())?;
    Some((c, r, cs.slice_of(pose.theta_rad) as u32))
}

fn is_free(cs: &CSpace, cell: CSpaceCell) -> bool {
    !cs.slices[cell.2 as usize].is_blocked(cell.0, cell.1)
}

/// Clearance by looking at every blocked cell of the pose's slice.
fn brute_clearance(cs: &CSpace, path: &[Pose]) -> f64 {
    path.iter()
        .map(|pose| {
            let g = &cs.slices[cs.slice_of(pose.theta_rad)];
            let p = pose.point();
            let (w, h) = g.size_mm();
            let mut best = p.x_mm.min(w - p.x_mm).min(p.y_mm).min(h - p.y_mm).max(0.0);
            for r in 0..g.height {
                for c in 0..g.width {
                    if g.is_blocked(c, r) {
                        let x0 = f64::from(c) * g.cell_mm;
                        let y0 = f64::from(g.height - 1 - r) * g.cell_mm;
                        let dx = (x0 - p.x_mm).max(p.x_mm - (x0 + g.cell_mm)).max(0.0);
                        let dy = (y0 - p.y_mm).max(p.y_mm - (y0 + g.cell_mm)).max(0.0);
                        best = best.min(dx.hypot(dy));
                    }
                }
            }
            best
        })
        .fold(f64::INFINITY, f64::min)
}

/// Every claim a plan (or its refusal) makes, checked by brute force.
fn check(
    cs: &CSpace,
    conn: Connectivity,
    start: Pose,
    goal: Pose,
    result: Result<Plan, NoPath>,
) -> Result<(), TestCaseError> {
    let (from, to) = (cell_of(cs, start).unwrap(), cell_of(cs, goal).unwrap());
    if !is_free(cs, from) || !is_free(cs, to) {
        prop_assert!(matches!(result, Err(NoPath::Blocked { .. })), "{result:?}");
        return Ok(());
    }
    let connected = flood_connected(cs, conn, from, to);
    let plan = match result {
        Err(NoPath::Disconnected) => {
            prop_assert!(!connected, "flood fill connects {from:?} to {to:?}");
            return Ok(());
        }
        Err(e) => return Err(TestCaseError::fail(format!("unexpected {e}"))),
        Ok(plan) => plan,
    };
    prop_assert!(connected);
    prop_assert_eq!(
        Some(plan.nf1_start_value),
        bfs(cs, conn, to).get(&from).copied()
    );
    // The descent: one NF1 value lower each step, by legal steps, to the goal.
    let nf1 = Nf1::from_goal(cs, to, conn);
    // The wave that stopped at the start descends as the whole one does.
    prop_assert_eq!(Some(plan.grid_path.clone()), nf1.descend(from, to));
    prop_assert_eq!(plan.grid_path.first(), Some(&from));
    prop_assert_eq!(plan.grid_path.last(), Some(&to));
    for (i, pair) in plan.grid_path.windows(2).enumerate() {
        prop_assert_eq!(
            nf1.value(pair[1]),
            Some(plan.nf1_start_value - i as u32 - 1)
        );
        prop_assert!(steps(cs, conn, pair[0]).contains(&pair[1]), "{pair:?}");
    }
    // The smooth path: from the start to the goal, never in a blocked cell.
    let (first, last) = (plan.path[0], *plan.path.last().unwrap());
    prop_assert!(first.point().distance(start.point()) < 1e-6);
    prop_assert!(last.point().distance(goal.point()) < 1e-6);
    for (i, pose) in plan.path.iter().enumerate() {
        let cell = cell_of(cs, *pose);
        prop_assert!(
            cell.is_some_and(|cell| is_free(cs, cell)),
            "sample {i} {pose:?} is in {cell:?}, blocked or off the map"
        );
    }
    for pair in plan.path.windows(2) {
        prop_assert!(pair[0].point().distance(pair[1].point()) <= CELL_MM / 4.0 + 1e-9);
    }
    let brute = brute_clearance(cs, &plan.path);
    prop_assert!(
        (plan.min_clearance_mm - brute).abs() < 1e-9,
        "clearance {} vs brute force {brute}",
        plan.min_clearance_mm
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn disc_robot_plans_agree_with_brute_force(
        map in random_map(),
        conn in connectivity(),
        radius in prop_oneof![Just(0.0), 0.0f64..16.0],
        s in (0.0f64..1.0, 0.0f64..1.0, -3.0f64..3.0),
        g in (0.0f64..1.0, 0.0f64..1.0, -3.0f64..3.0),
        snap in proptest::bool::weighted(0.85),
    ) {
        let cs = CSpace::build(&map, Footprint::Disc { radius_mm: radius }, 1).unwrap();
        let (start, goal) = (pose_on(&cs, s, snap), pose_on(&cs, g, snap));
        check(&cs, conn, start, goal, plan(&cs, start, goal, conn))?;
    }

    #[test]
    fn polygon_robot_plans_agree_with_brute_force(
        map in random_map(),
        conn in connectivity(),
        slices in 2u32..7,
        length in 5.0f64..25.0,
        s in (0.0f64..1.0, 0.0f64..1.0, -3.0f64..3.0),
        g in (0.0f64..1.0, 0.0f64..1.0, -3.0f64..3.0),
        snap in proptest::bool::weighted(0.85),
    ) {
        // A bar along the robot's x axis: it fits through a gap only end-on.
        let bar = Footprint::Polygon { points: vec![
            Point { x_mm: -length, y_mm: -2.0 },
            Point { x_mm: length, y_mm: -2.0 },
            Point { x_mm: length, y_mm: 2.0 },
            Point { x_mm: -length, y_mm: 2.0 },
        ]};
        let cs = CSpace::build(&map, bar, slices).unwrap();
        let (start, goal) = (pose_on(&cs, s, snap), pose_on(&cs, g, snap));
        check(&cs, conn, start, goal, plan(&cs, start, goal, conn))?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Clearance of any poses, near obstacles or far from them (so every
    /// way `clearance` looks is taken: a few cells out, farther, the whole
    /// map), equals the exhaustive search's.
    #[test]
    fn clearance_of_any_poses_agrees_with_brute_force(
        (w, h, blocked) in (20u32..70, 20u32..70, 0.0f64..0.03).prop_flat_map(|(w, h, density)| {
            (Just(w), Just(h), proptest::collection::vec(proptest::bool::weighted(density), (w * h) as usize))
        }),
        poses in proptest::collection::vec((0.0f64..1.0, 0.0f64..1.0), 1..12),
    ) {
        let map = Grid { width: w, height: h, cell_mm: CELL_MM, blocked };
        let cs = CSpace::build(&map, Footprint::Disc { radius_mm: 0.0 }, 1).unwrap();
        let (wmm, hmm) = map.size_mm();
        let path: Vec<Pose> = poses
            .iter()
            .map(|&(fx, fy)| Pose { x_mm: fx * wmm, y_mm: fy * hmm, theta_rad: 0.0 })
            .collect();
        let got = clearance(&cs, &path);
        let brute = brute_clearance(&cs, &path);
        prop_assert!((got - brute).abs() < 1e-9, "clearance {got} vs brute force {brute}");
    }
}

#[test]
fn a_start_off_the_map_is_named() {
    let map = Grid::free(5, 5, CELL_MM).unwrap();
    let cs = CSpace::build(&map, Footprint::Disc { radius_mm: 0.0 }, 1).unwrap();
    let outside = Pose {
        x_mm: -1.0,
        y_mm: 10.0,
        theta_rad: 0.0,
    };
    let err = plan(&cs, outside, Pose::default(), Connectivity::Four).unwrap_err();
    assert!(
        err.to_string()
            .contains("start (-1.0, 10.0) mm is off the map"),
        "{err}"
    );
}

/// A point anywhere on the open arena (600 × 600 mm), kept a robot's
/// width from its walls.
fn open_point() -> impl Strategy<Value = Point> {
    (60.0f64..540.0, 60.0f64..540.0).prop_map(|(x_mm, y_mm)| Point { x_mm, y_mm })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A path planned through points visits each of them in order: a
    /// robot walking its samples counts them all (`Visited`), the run ends
    /// there (`Definition::reached`), and its length is its legs'.
    #[test]
    fn a_path_through_points_visits_each_in_order(
        points in proptest::collection::vec(open_point(), 1..5),
    ) {
        let arena = vl_core::Arena::load("open").unwrap();
        let robot = vl_core::RobotModel::khepera_ii();
        let start = arena.start;
        let whole = vl_core::plan_route_through(&arena, &[], &robot, start, &points, 25.0).unwrap();
        let definition = vl_core::Definition {
            goal: Some(vl_core::Goal::at(*points.last().unwrap())),
            waypoints: points.clone(),
            path: whole.points(),
            ..vl_core::Definition::default()
        };
        let mut visited = vl_core::Visited::default();
        for p in &definition.path {
            visited = visited.at(&definition, *p);
        }
        prop_assert_eq!(visited.0, points.len());
        prop_assert!(definition.reached(visited, *definition.path.last().unwrap()));
        let mut from = start;
        let mut legs = 0.0;
        for &p in &points {
            let leg = vl_core::plan_route_with_margin(&arena, &[], &robot, from, p, 25.0).unwrap();
            from = *leg.path.last().unwrap();
            legs += leg.length_mm;
        }
        prop_assert!((whole.length_mm - legs).abs() < 1e-6, "{} vs {}", whole.length_mm, legs);
    }

    /// The count of waypoints visited only grows, one at a time, and only
    /// where the next is within the tolerance; a run ends with all of them.
    #[test]
    fn waypoints_are_counted_in_order_only(
        waypoints in proptest::collection::vec(open_point(), 1..6),
        walk in proptest::collection::vec(open_point(), 0..60),
    ) {
        let definition = vl_core::Definition {
            waypoints: waypoints.clone(),
            ..vl_core::Definition::default()
        };
        let tolerance = definition.tolerance_mm();
        let mut visited = vl_core::Visited::default();
        for p in walk.iter().chain(&waypoints) {
            let next = visited.at(&definition, *p);
            match next.0 - visited.0 {
                0 => prop_assert!(waypoints.get(visited.0).is_none_or(|w| w.distance(*p) > tolerance)),
                1 => prop_assert!(waypoints[visited.0].distance(*p) <= tolerance),
                _ => prop_assert!(false, "counted two at once"),
            }
            prop_assert_eq!(definition.reached(next, *p), next.0 == waypoints.len());
            visited = next;
        }
        prop_assert_eq!(visited.0, waypoints.len(), "walking them in order visits them all");
    }
}
