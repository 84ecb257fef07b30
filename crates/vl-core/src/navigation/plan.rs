//! Path planning on a C-space, as the mobile-robotics lab does it: the NF1
//! wavefront from the goal, steepest descent from the start, a cubic spline
//! through the descent's cells, and a check that the smooth path stays in
//! free C-space, with the clearance it keeps.

use serde::Serialize;
use thiserror::Error;

use super::follow::PLAN_MARGIN_MM;
use super::spline::{Knot, Spline};
use crate::{
    Arena, CSpace, CSpaceCell, CSpaceError, Connectivity, FAR, Footprint, Grid, Nf1, Point, Pose,
    RobotModel, Shape, Surroundings, wrap_angle,
};

/// Cells of the descent between spline knots, before refinement.
const KNOT_STRIDE: usize = 6;
/// Spline samples per cell of path length.
const SAMPLES_PER_CELL: f64 = 4.0;

/// Why there is no path.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NoPath {
    #[error("the {which} ({x:.1}, {y:.1}) mm is off the map, which spans 0–{w:.1} × 0–{h:.1} mm")]
    OffMap {
        which: PathEnd,
        x: f64,
        y: f64,
        w: f64,
        h: f64,
    },
    #[error(
        "the {which} ({x:.1}, {y:.1}) mm lies in an obstacle of the C-space (the robot would touch one there)"
    )]
    Blocked { which: PathEnd, x: f64, y: f64 },
    #[error("the start and the goal are not connected in free C-space")]
    Disconnected,
}

/// The start or the goal of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathEnd {
    Start,
    Goal,
}

impl std::fmt::Display for PathEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PathEnd::Start => "start",
            PathEnd::Goal => "goal",
        })
    }
}

/// How the path was smoothed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Smoothing {
    /// A cubic spline through this many knots.
    Spline { knots: usize },
    /// Straight lines between the descent's cell centres: no spline through
    /// them stayed clear of the obstacles.
    Polyline,
}

/// A planned path.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The start cell's NF1 value: grid steps to the goal.
    pub nf1_start_value: u32,
    /// The descent, start cell to goal cell.
    pub grid_path: Vec<CSpaceCell>,
    /// The smooth path's samples, start to goal, at most a quarter cell
    /// apart. θ is the planned heading for a polygon robot, and the path's
    /// direction for a disc.
    pub path: Vec<Pose>,
    pub length_mm: f64,
    /// The least distance from a sample to a blocked C-space cell or the
    /// map's edge: how far the robot could stray before touching something.
    pub min_clearance_mm: f64,
    pub smoothing: Smoothing,
}

impl Plan {
    /// The smooth path's positions, start to goal: what a follower steers along.
    pub fn points(&self) -> Vec<Point> {
        self.path.iter().map(|p| p.point()).collect()
    }

    /// This plan, then `next`, which starts where this one ends: one path.
    #[must_use]
    fn then(mut self, next: Plan) -> Plan {
        self.nf1_start_value += next.nf1_start_value;
        self.grid_path.extend(next.grid_path.into_iter().skip(1));
        self.path.extend(next.path.into_iter().skip(1));
        self.length_mm += next.length_mm;
        self.min_clearance_mm = self.min_clearance_mm.min(next.min_clearance_mm);
        self.smoothing = match (self.smoothing, next.smoothing) {
            (Smoothing::Spline { knots: a }, Smoothing::Spline { knots: b }) => {
                Smoothing::Spline { knots: a + b }
            }
            _ => Smoothing::Polyline,
        };
        self
    }
}

/// The cell the robot stands in at `pose`, if it is free.
pub(crate) fn locate(cspace: &CSpace, pose: Pose, which: PathEnd) -> Result<CSpaceCell, NoPath> {
    let grid = cspace.grid();
    let (w, h) = grid.size_mm();
    let (c, r) = grid.cell_of(pose.point()).ok_or(NoPath::OffMap {
        which,
        x: pose.x_mm,
        y: pose.y_mm,
        w,
        h,
    })?;
    let k = cspace.slice_of(pose.theta_rad);
    if cspace.slices[k].is_blocked(c, r) {
        return Err(NoPath::Blocked {
            which,
            x: pose.x_mm,
            y: pose.y_mm,
        });
    }
    Ok((c, r, k as u32))
}

/// CSpaceCell size for planning on an arena's obstacle list.
pub const ARENA_CELL_MM: f64 = 5.0;

/// Why a path in an arena could not be planned.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ArenaPlanError {
    #[error(transparent)]
    Map(#[from] CSpaceError),
    #[error(transparent)]
    NoPath(#[from] NoPath),
}

/// A path for a disc robot of `radius_mm` across `arena` (plus virtual
/// obstacles), on cells of [`ARENA_CELL_MM`], keeping `margin_mm` more than
/// the radius from obstacles, or as much of it as the narrowest passage on
/// the way (and the start and goal) allow.
pub(crate) fn plan_in_arena(
    arena: &Arena,
    virtual_obstacles: &[Shape],
    radius_mm: f64,
    margin_mm: f64,
    start: Pose,
    goal: Point,
) -> Result<Plan, ArenaPlanError> {
    let mut grid = Grid::from_arena(arena, ARENA_CELL_MM)?;
    for shape in virtual_obstacles {
        grid.block(shape);
    }
    let goal = Pose {
        x_mm: goal.x_mm,
        y_mm: goal.y_mm,
        theta_rad: 0.0,
    };
    let mut result: Result<Plan, ArenaPlanError> = Err(NoPath::Disconnected.into());
    // Narrow passages, or a start or goal close to an obstacle, may leave
    // room for less margin; the robot's body must still fit.
    for extra in [1.0, 0.6, 0.4, 0.2, 0.0].map(|f| f * margin_mm) {
        let footprint = Footprint::Disc {
            radius_mm: radius_mm + extra,
        };
        let cspace = CSpace::build(&grid, footprint, 1)?;
        result = plan(&cspace, start, goal, Connectivity::Eight).map_err(Into::into);
        if result.is_ok() {
            break;
        }
    }
    let mut plan = result?;
    let surroundings = Surroundings::new(arena).with(virtual_obstacles);
    keep_clear(
        &mut plan.path,
        |p| surroundings.clearance(p) - radius_mm,
        margin_mm,
    );
    plan.length_mm = length_mm(&plan.path);
    Ok(plan)
}

/// The length of the polyline through `path`'s positions, mm.
fn length_mm(path: &[Pose]) -> f64 {
    path.windows(2)
        .map(|w| w[0].point().distance(w[1].point()))
        .sum()
}

/// Rounds of [`keep_clear`], and the most one round moves a point, mm.
const CLEARING_ROUNDS: usize = 60;
const CLEARING_STEP_MM: f64 = 0.5;

/// Moves the path's inner samples away from whatever is nearer than
/// `margin_mm` (by `room`, the body's clearance at a point), as far as the
/// room allows, keeping the path smooth. The margin lowered for a narrow
/// passage is then lowered there only: elsewhere the path keeps its margin,
/// and in the passage it runs down the middle, where a guard that keeps a
/// few millimetres lets it through. A path that would come out nearer to
/// anything than it went in is left as it was.
fn keep_clear(path: &mut [Pose], room: impl Fn(Point) -> f64, margin_mm: f64) {
    let n = path.len();
    if n < 3 {
        return;
    }
    let least = |path: &[Pose]| {
        path.iter()
            .map(|p| room(p.point()))
            .fold(f64::INFINITY, f64::min)
    };
    let before = least(path);
    let mut points: Vec<Point> = path.iter().map(|p| p.point()).collect();
    let h = 0.5;
    for _ in 0..CLEARING_ROUNDS {
        let mut moved = false;
        for point in &mut points[1..n - 1] {
            let p = *point;
            let c = room(p);
            if c >= margin_mm {
                continue;
            }
            let at = |dx: f64, dy: f64| {
                room(Point {
                    x_mm: p.x_mm + dx,
                    y_mm: p.y_mm + dy,
                })
            };
            let (gx, gy) = (
                (at(h, 0.0) - at(-h, 0.0)) / (2.0 * h),
                (at(0.0, h) - at(0.0, -h)) / (2.0 * h),
            );
            let norm = gx.hypot(gy);
            if norm < 1e-6 {
                continue;
            }
            let step = (margin_mm - c).min(CLEARING_STEP_MM);
            *point = Point {
                x_mm: p.x_mm + gx / norm * step,
                y_mm: p.y_mm + gy / norm * step,
            };
            moved = true;
        }
        // A light smoothing keeps the pushed samples a smooth curve.
        let pushed = points.clone();
        for i in 1..n - 1 {
            points[i] = Point {
                x_mm: 0.5 * pushed[i].x_mm + 0.25 * (pushed[i - 1].x_mm + pushed[i + 1].x_mm),
                y_mm: 0.5 * pushed[i].y_mm + 0.25 * (pushed[i - 1].y_mm + pushed[i + 1].y_mm),
            };
        }
        if !moved {
            break;
        }
    }
    let mut cleared: Vec<Pose> = path.to_vec();
    for i in 1..n - 1 {
        let (a, b) = (points[i - 1], points[i + 1]);
        cleared[i] = Pose {
            x_mm: points[i].x_mm,
            y_mm: points[i].y_mm,
            theta_rad: (b.y_mm - a.y_mm).atan2(b.x_mm - a.x_mm),
        };
    }
    if least(&cleared) >= before {
        path.copy_from_slice(&cleared);
    }
}

/// The C-space of a disc robot of `radius_mm` on `arena` and its virtual
/// obstacles, on cells of [`ARENA_CELL_MM`]: where the robot's centre may
/// not go. The Host's map field pushes from it; the Guest shows it.
pub fn disc_cspace(
    arena: &Arena,
    virtual_obstacles: &[Shape],
    radius_mm: f64,
) -> Result<CSpace, CSpaceError> {
    let mut grid = Grid::from_arena(arena, ARENA_CELL_MM)?;
    for shape in virtual_obstacles {
        grid.block(shape);
    }
    CSpace::build(&grid, Footprint::Disc { radius_mm }, 1)
}

/// The path a Guest defines for `robot` from `start` to `goal`: planned on
/// the arena's map around the virtual obstacles, keeping
/// [`PLAN_MARGIN_MM`] from mapped obstacles where the passages allow, so
/// that only what the map does not show makes the sensors take over.
pub fn plan_route(
    arena: &Arena,
    virtual_obstacles: &[Shape],
    robot: &RobotModel,
    start: Pose,
    goal: Point,
) -> Result<Plan, ArenaPlanError> {
    plan_route_with_margin(arena, virtual_obstacles, robot, start, goal, PLAN_MARGIN_MM)
}

/// [`plan_route`], keeping `margin_mm` instead where the passages allow
/// (a user's setting, thesis F.6).
pub fn plan_route_with_margin(
    arena: &Arena,
    virtual_obstacles: &[Shape],
    robot: &RobotModel,
    start: Pose,
    goal: Point,
    margin_mm: f64,
) -> Result<Plan, ArenaPlanError> {
    plan_in_arena(
        arena,
        virtual_obstacles,
        robot.radius_mm,
        margin_mm,
        start,
        goal,
    )
}

/// [`plan_route_with_margin`] through `points` in order: each leg from
/// where the last ended, as it ended (its heading), joined into one path.
pub fn plan_route_through(
    arena: &Arena,
    virtual_obstacles: &[Shape],
    robot: &RobotModel,
    start: Pose,
    points: &[Point],
    margin_mm: f64,
) -> Result<Plan, ArenaPlanError> {
    let mut whole: Option<Plan> = None;
    let mut from = start;
    for &to in points {
        let leg = plan_route_with_margin(arena, virtual_obstacles, robot, from, to, margin_mm)?;
        from = leg.path.last().copied().unwrap_or(from);
        whole = Some(match whole {
            Some(so_far) => so_far.then(leg),
            None => leg,
        });
    }
    whole.ok_or(ArenaPlanError::NoPath(NoPath::Disconnected))
}

/// Plans from `start` to `goal`.
pub fn plan(
    cspace: &CSpace,
    start: Pose,
    goal: Pose,
    connectivity: Connectivity,
) -> Result<Plan, NoPath> {
    let from = locate(cspace, start, PathEnd::Start)?;
    let to = locate(cspace, goal, PathEnd::Goal)?;
    let nf1 = Nf1::toward(cspace, to, from, connectivity);
    let nf1_start_value = nf1.value(from).ok_or(NoPath::Disconnected)?;
    let grid_path = nf1.descend(from, to).ok_or(NoPath::Disconnected)?;
    let (path, smoothing) = smooth(cspace, start, goal, &grid_path);
    let length_mm = length_mm(&path);
    Ok(Plan {
        nf1_start_value,
        min_clearance_mm: clearance(cspace, &path),
        grid_path,
        path,
        length_mm,
        smoothing,
    })
}

/// The heading coordinate's scale: turning by one radian counts as moving
/// this far, so rotations in place still advance the spline's parameter.
fn heading_mm(cspace: &CSpace) -> f64 {
    if cspace.slices.len() == 1 {
        0.0
    } else {
        cspace.footprint.reach_mm().max(cspace.grid().cell_mm)
    }
}

/// Spline knots (x, y, scaled unwrapped θ) for each cell of the descent,
/// with the real start and goal poses in place of their cells' centres.
fn knots(cspace: &CSpace, start: Pose, goal: Pose, cells: &[CSpaceCell]) -> Vec<Knot> {
    let grid = cspace.grid();
    let rho = heading_mm(cspace);
    let mut theta = start.theta_rad;
    let mut out: Vec<Knot> = cells
        .iter()
        .map(|&(c, r, k)| {
            theta += wrap_angle(cspace.theta_of(k as usize) - theta);
            let p = grid.centre(c, r);
            [p.x_mm, p.y_mm, theta * rho]
        })
        .collect();
    let goal_theta = theta + wrap_angle(goal.theta_rad - theta);
    let goal = [goal.x_mm, goal.y_mm, goal_theta * rho];
    if out.len() == 1 {
        out.push(goal);
    } else if let Some(last) = out.last_mut() {
        *last = goal;
    }
    out[0] = [start.x_mm, start.y_mm, start.theta_rad * rho];
    out
}

/// The smooth path along the descent `cells`: a chord-length cubic spline
/// through every few cells, with knots added wherever a sample falls in a
/// blocked cell, or straight lines between cell centres when even a knot
/// at every cell does not keep it clear.
pub(crate) fn smooth(
    cspace: &CSpace,
    start: Pose,
    goal: Pose,
    cells: &[CSpaceCell],
) -> (Vec<Pose>, Smoothing) {
    let all = knots(cspace, start, goal, cells);
    let step = cspace.grid().cell_mm / SAMPLES_PER_CELL;
    let rho = heading_mm(cspace);
    let to_pose = |k: &Knot, tangent: f64| Pose {
        x_mm: k[0],
        y_mm: k[1],
        theta_rad: if rho > 0.0 {
            wrap_angle(k[2] / rho)
        } else {
            tangent
        },
    };
    let free = |k: &Knot| {
        let theta = if rho > 0.0 { k[2] / rho } else { 0.0 };
        cspace.is_free(
            Point {
                x_mm: k[0],
                y_mm: k[1],
            },
            theta,
        )
    };
    let last = all.len() - 1;
    let mut chosen: Vec<usize> = (0..last).step_by(KNOT_STRIDE).chain([last]).collect();
    loop {
        let spline = Spline::through(&chosen.iter().map(|&i| all[i]).collect::<Vec<_>>());
        let (samples, mut bad) = sample_checked(&spline, step, &free);
        if bad.is_empty() {
            let knots = chosen.len();
            return (poses(&samples, to_pose), Smoothing::Spline { knots });
        }
        bad.dedup();
        if bad.iter().any(|&j| chosen[j + 1] - chosen[j] < 2) {
            break;
        }
        // A knot halfway (along the descent) into each interval that strayed.
        for &j in bad.iter().rev() {
            chosen.insert(j + 1, (chosen[j] + chosen[j + 1]) / 2);
        }
    }
    // Straight segments between neighbouring free cells stay within them.
    let mut samples = Vec::new();
    for pair in all.windows(2) {
        let line = Spline::through(pair);
        let part = line.sample(step);
        let skip = usize::from(!samples.is_empty());
        samples.extend(part.into_iter().skip(skip));
    }
    (poses(&samples, to_pose), Smoothing::Polyline)
}

/// Splines with at least this many intervals are sampled and checked by two
/// threads, half each: below it, starting a thread costs more than it saves.
const PARALLEL_INTERVALS: usize = 256;

/// The spline's samples `step` apart, and the interval of each that is not
/// `free` (in order, repeated per sample).
fn sample_checked(
    spline: &Spline,
    step: f64,
    free: &(impl Fn(&Knot) -> bool + Sync),
) -> (Vec<(f64, Knot)>, Vec<usize>) {
    let part = |intervals: std::ops::Range<usize>| {
        let samples = spline.sample_intervals(intervals, step);
        let bad: Vec<usize> = samples
            .iter()
            .filter(|(_, k)| !free(k))
            .map(|&(t, _)| spline.interval(t))
            .collect();
        (samples, bad)
    };
    let n = spline.intervals();
    if n < PARALLEL_INTERVALS {
        return part(0..n);
    }
    std::thread::scope(|scope| {
        let later = scope.spawn(|| part(n / 2..n));
        let (mut samples, mut bad) = part(0..n / 2);
        let (more, worse) = later.join().expect("sampling does not panic");
        samples.extend(more);
        bad.extend(worse);
        (samples, bad)
    })
}

/// Samples as poses, θ from the direction to the next sample where the
/// knots carry no heading.
fn poses(samples: &[(f64, Knot)], to_pose: impl Fn(&Knot, f64) -> Pose) -> Vec<Pose> {
    let mut tangent = 0.0;
    samples
        .iter()
        .enumerate()
        .map(|(i, (_, k))| {
            if let Some((_, next)) = samples.get(i + 1) {
                let (dx, dy) = (next[0] - k[0], next[1] - k[1]);
                if dx != 0.0 || dy != 0.0 {
                    tangent = dy.atan2(dx);
                }
            }
            to_pose(k, tangent)
        })
        .collect()
}

/// The least distance from any pose of `path` to a blocked cell (as a
/// square) of its heading's slice, or to the map's edge; 0 for a pose in a
/// blocked cell.
///
/// A planned path passes near the C-space's edge, so each pose first looks
/// only at the cells a few cells around it; only a path that keeps farther
/// than that from everything needs a distance transform of the whole map.
pub fn clearance(cspace: &CSpace, path: &[Pose]) -> f64 {
    CLEARANCE_REACH_CELLS
        .iter()
        .find_map(|&reach| clearance_near(cspace, path, reach))
        .unwrap_or_else(|| clearance_by_transform(cspace, path))
}

/// How near, in cells, [`clearance`] looks around each pose, in turn.
const CLEARANCE_REACH_CELLS: [u32; 2] = [2, 8];

/// The clearance when it is at most `reach` cells, else None. A square
/// within `reach` cells of a pose has its centre within `reach + √2` cells
/// of the pose's cell's centre, so the window of `reach + 2` cells around
/// that cell holds it; poses in one cell share one look at the window.
fn clearance_near(cspace: &CSpace, path: &[Pose], reach: u32) -> Option<f64> {
    let window = i64::from(reach) + 2;
    let part = |poses: &[Pose]| nearest2_near(cspace, poses, window);
    let best2 = if path.len() < PARALLEL_POSES {
        part(path)
    } else {
        let (first, second) = path.split_at(path.len() / 2);
        std::thread::scope(|scope| {
            let later = scope.spawn(|| part(second));
            let best2 = part(first);
            best2.min(later.join().expect("clearance does not panic"))
        })
    };
    let best = best2.sqrt();
    let cell_mm = cspace.grid().cell_mm;
    (best <= f64::from(reach) * cell_mm).then_some(best)
}

/// Paths with at least this many poses have their clearance taken by two
/// threads, half each.
const PARALLEL_POSES: usize = 4096;

/// The least squared distance from the poses to a blocked square within
/// `window` cells of each pose's cell, or to the map's edge (0 for a pose
/// off the map).
fn nearest2_near(cspace: &CSpace, path: &[Pose], window: i64) -> f64 {
    let mut best2 = f64::INFINITY;
    let mut squares: Vec<Point> = Vec::new();
    let mut scanned: Option<(usize, u32, u32)> = None;
    for pose in path {
        let k = cspace.slice_of(pose.theta_rad);
        let grid = &cspace.slices[k];
        let p = pose.point();
        let Some((c, r)) = grid.cell_of(p) else {
            return 0.0;
        };
        if scanned != Some((k, c, r)) {
            scanned = Some((k, c, r));
            blocked_centres(grid, (c, r), window, &mut squares);
            // A square whose centre is more than 1.5 diagonals farther from
            // the cell's centre than the nearest one is never nearer to a
            // point in the cell.
            let centre = grid.centre(c, r);
            let dist2 = |q: &Point| (q.x_mm - centre.x_mm).powi(2) + (q.y_mm - centre.y_mm).powi(2);
            let nearest2 = squares.iter().map(dist2).fold(f64::INFINITY, f64::min);
            let keep = nearest2.sqrt() + 1.5 * std::f64::consts::SQRT_2 * grid.cell_mm;
            squares.retain(|q| dist2(q) <= keep * keep);
        }
        let edge = edge_distance(grid, p);
        best2 = best2
            .min(edge * edge)
            .min(nearest_square2(grid.cell_mm, &squares, p));
    }
    best2
}

/// The squared distance from `p` to the nearest of the squares (cells of
/// side `cell_mm`) centred at `centres`; infinite for none.
fn nearest_square2(cell_mm: f64, centres: &[Point], p: Point) -> f64 {
    centres
        .iter()
        .map(|centre| {
            let dx = ((centre.x_mm - p.x_mm).abs() - cell_mm / 2.0).max(0.0);
            let dy = ((centre.y_mm - p.y_mm).abs() - cell_mm / 2.0).max(0.0);
            dx * dx + dy * dy
        })
        .fold(f64::INFINITY, f64::min)
}

/// The clearance of a path that keeps far from everything: the distance
/// transform gives each pose a lower bound; poses are then checked
/// exactly, nearest first, until no bound can beat the best found.
fn clearance_by_transform(cspace: &CSpace, path: &[Pose]) -> f64 {
    let mut transforms: Vec<Option<Vec<u32>>> = vec![None; cspace.slices.len()];
    // (lower bound, pose, slice, squared cells to the nearest blocked centre)
    let mut candidates: Vec<(f64, usize, usize, f64)> = Vec::with_capacity(path.len());
    for (i, pose) in path.iter().enumerate() {
        let k = cspace.slice_of(pose.theta_rad);
        let grid = &cspace.slices[k];
        let Some((c, r)) = grid.cell_of(pose.point()) else {
            return 0.0;
        };
        let d2 = transforms[k].get_or_insert_with(|| grid.distance_transform());
        // FAR: no blocked cell within the transform's reach; search to the edge.
        let centre_d2 = match d2[grid.index(c, r)] {
            FAR => f64::INFINITY,
            d2 => f64::from(d2),
        };
        let bound = (centre_d2.sqrt() - std::f64::consts::SQRT_2).max(0.0) * grid.cell_mm;
        candidates.push((
            bound.min(edge_distance(grid, pose.point())),
            i,
            k,
            centre_d2,
        ));
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = f64::INFINITY;
    for (bound, i, k, centre_d2) in candidates {
        if bound >= best {
            break;
        }
        best = best.min(exact_clearance(
            &cspace.slices[k],
            centre_d2,
            path[i].point(),
        ));
    }
    if best.is_finite() { best } else { 0.0 }
}

fn edge_distance(grid: &Grid, p: Point) -> f64 {
    let (w, h) = grid.size_mm();
    p.x_mm.min(w - p.x_mm).min(p.y_mm).min(h - p.y_mm).max(0.0)
}

/// Distance from `p` to the nearest blocked cell's square or the map edge,
/// searching the cells the distance transform says could be nearest.
fn exact_clearance(grid: &Grid, centre_d2: f64, p: Point) -> f64 {
    let s = grid.cell_mm;
    let Some(cell) = grid.cell_of(p) else {
        return 0.0;
    };
    let edge = edge_distance(grid, p);
    // The nearest blocked centre is within sqrt(d2) cells of this cell's
    // centre, so its square is within that plus half a diagonal of p; any
    // square at least that near has its centre within 1.5 diagonals more.
    let bound = (centre_d2.sqrt() * s + s * std::f64::consts::FRAC_1_SQRT_2).min(edge);
    let reach = (bound / s + 1.5 * std::f64::consts::SQRT_2).ceil() as i64;
    let mut squares = Vec::new();
    blocked_centres(grid, cell, reach, &mut squares);
    (edge * edge).min(nearest_square2(s, &squares, p)).sqrt()
}

/// Puts into `out` the centres of the blocked cells within `window` cells
/// (along each axis) of `cell`.
fn blocked_centres(grid: &Grid, (c, r): (u32, u32), window: i64, out: &mut Vec<Point>) {
    out.clear();
    let (c, r) = (i64::from(c), i64::from(r));
    for rr in (r - window).max(0)..=(r + window).min(i64::from(grid.height) - 1) {
        for cc in (c - window).max(0)..=(c + window).min(i64::from(grid.width) - 1) {
            if grid.is_blocked(cc as u32, rr as u32) {
                out.push(grid.centre(cc as u32, rr as u32));
            }
        }
    }
}
