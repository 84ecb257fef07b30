//! The report's pictures, drawn once as SVG and once as PNG with `plotters`
//! (its text in the Ubuntu font egui already ships, so nothing is needed
//! from the system).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use vl_core::{Arena, Point, Shape};

/// Why a picture could not be drawn (or written).
#[derive(Debug, thiserror::Error)]
#[error("cannot draw {what}: {why}")]
pub struct PlotError {
    pub what: String,
    pub why: String,
}

type Result<T> = std::result::Result<T, PlotError>;

const SIZE: (u32, u32) = (800, 480);
const FONT: &str = "sans-serif";

/// Series colours: the first for event-based runs, the second for time-based.
pub const EVENT: RGBColor = RGBColor(0x1f, 0x77, 0xb4);
pub const TIME: RGBColor = RGBColor(0xd6, 0x27, 0x28);
const PLANNED: RGBColor = RGBColor(0x99, 0x99, 0x99);
const OBSTACLE: RGBColor = RGBColor(0x55, 0x58, 0x60);
/// What the chart's frame takes besides the plot area, px: the y labels
/// and margins across, the title, x labels and margins down.
const AXES_PX: (u32, u32) = (52 + 24, 36 + 30 + 24);
/// A third series where there is one.
pub const THIRD: RGBColor = RGBColor(0x2c, 0xa0, 0x2c);

fn font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // Registration fails only for a malformed font, which this is not;
        // text would then be left out rather than the picture.
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// A picture drawn the same on any backend.
trait Picture {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>;
}

/// Draws `picture` into `dir/name.svg` and `dir/name.png`; returns the PNG's name.
fn both(dir: &Path, name: &str, picture: &impl Picture) -> Result<PathBuf> {
    both_sized(dir, name, picture, SIZE)
}

/// [`both`], `size` px.
fn both_sized(dir: &Path, name: &str, picture: &impl Picture, size: (u32, u32)) -> Result<PathBuf> {
    font();
    let svg = dir.join(format!("{name}.svg"));
    let png = dir.join(format!("{name}.png"));
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        picture.draw(&root)?;
        root.present().map_err(|e| draw_error(&svg, e))?;
    }
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        picture.draw(&root)?;
        root.present().map_err(|e| draw_error(&png, e))?;
    }
    Ok(PathBuf::from(format!("{name}.png")))
}

fn err(e: impl std::fmt::Display) -> PlotError {
    PlotError {
        what: "a plot".into(),
        why: e.to_string(),
    }
}

fn draw_error(file: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError {
        what: file.display().to_string(),
        why: e.to_string(),
    }
}

/// A chart with the report's look: white, titled, its axes labelled.
type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn chart<'a, DB: DrawingBackend>(
    root: &'a DrawingArea<DB, Shift>,
    title: &str,
    (x, y): (f64, f64),
    (x_desc, y_desc): (&str, &str),
) -> Result<Chart<'a, DB>> {
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(0.0..x, 0.0..y)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 13))
        .draw()
        .map_err(err)?;
    Ok(chart)
}

/// Draws the chart's legend at `position`.
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    position: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 14))
        .draw()
        .map_err(err)
}

/// A histogram of each leg's one-way delays, ms.
pub fn delays(dir: &Path, name: &str, title: &str, legs: &[(&str, &[f64])]) -> Result<PathBuf> {
    let all: Vec<f64> = legs.iter().flat_map(|(_, v)| v.iter().copied()).collect();
    let mut sorted = all.clone();
    sorted.sort_by(f64::total_cmp);
    let top = sorted
        .get((sorted.len() as f64 * 0.995) as usize)
        .copied()
        .unwrap_or(1.0)
        .max(1.0)
        * 1.05;
    const BINS: usize = 60;
    let width = top / BINS as f64;
    let counts: Vec<Vec<f64>> = legs
        .iter()
        .map(|(_, v)| {
            let mut c = vec![0.0; BINS];
            for &d in *v {
                c[((d / width) as usize).min(BINS - 1)] += 1.0;
            }
            let n = v.len().max(1) as f64;
            c.iter().map(|k| k / n).collect()
        })
        .collect();
    let peak = counts.iter().flatten().fold(0.0f64, |a, &b| a.max(b)) * 1.1;
    struct Histogram<'a> {
        title: &'a str,
        legs: &'a [(&'a str, &'a [f64])],
        counts: Vec<Vec<f64>>,
        top: f64,
        width: f64,
        peak: f64,
    }
    impl Picture for Histogram<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let Histogram {
                title,
                legs,
                counts,
                top,
                width,
                peak,
            } = self;
            let (top, width, peak) = (*top, *width, *peak);
            let mut chart = chart(
                root,
                title,
                (top, peak.max(0.01)),
                (
                    "one-way delay, ms (measured at the Media)",
                    "share of messages",
                ),
            )?;
            for (k, ((leg, _), c)) in legs.iter().zip(counts.iter()).enumerate() {
                let colour = [EVENT, TIME, THIRD][k % 3];
                // Each leg as a step outline, so overlapping legs stay readable.
                let steps = c.iter().enumerate().flat_map(|(i, &share)| {
                    let x0 = i as f64 * width;
                    [(x0, share), (x0 + width, share)]
                });
                chart
                    .draw_series(LineSeries::new(steps, colour.stroke_width(2)))
                    .map_err(err)?
                    .label(*leg)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
            }
            legend(&mut chart, SeriesLabelPosition::UpperRight)
        }
    }
    both(
        dir,
        name,
        &Histogram {
            title,
            legs,
            counts,
            top,
            width,
            peak,
        },
    )
}

/// A labelled, coloured series of (x, y) points.
pub type Series = (String, RGBColor, Vec<(f64, f64)>);

/// How a series' points are drawn: joined where they sample something
/// continuous, apart where they are sparse or categories.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marks {
    Lines,
    LinesAndPoints,
    Points,
}

/// Lines of (x, y) points, one per labelled series.
pub fn lines(
    dir: &Path,
    name: &str,
    title: &str,
    axes: (&str, &str),
    series: &[Series],
    marks: Marks,
) -> Result<PathBuf> {
    let xs = series.iter().flat_map(|(_, _, v)| v.iter().map(|p| p.0));
    let ys = series.iter().flat_map(|(_, _, v)| v.iter().map(|p| p.1));
    let x_max = xs.fold(0.0f64, f64::max).max(1e-3) * 1.05;
    let y_max = ys.fold(0.0f64, f64::max).max(1e-3) * 1.1;
    struct LineChart<'a> {
        title: &'a str,
        axes: (&'a str, &'a str),
        series: &'a [Series],
        marks: Marks,
        x_max: f64,
        y_max: f64,
    }
    impl Picture for LineChart<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let LineChart {
                title,
                axes,
                series,
                marks,
                x_max,
                y_max,
            } = self;
            let (x_max, y_max, marks) = (*x_max, *y_max, *marks);
            let mut chart = chart(root, title, (x_max, y_max), *axes)?;
            for (label, colour, data) in series.iter() {
                let colour = *colour;
                let line = marks != Marks::Points;
                let drawn = if line {
                    chart.draw_series(LineSeries::new(
                        data.iter().copied(),
                        colour.stroke_width(2),
                    ))
                } else {
                    chart.draw_series(data.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                };
                drawn
                    .map_err(err)?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
                if marks == Marks::LinesAndPoints {
                    chart
                        .draw_series(data.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                        .map_err(err)?;
                }
            }
            legend(&mut chart, SeriesLabelPosition::UpperLeft)
        }
    }
    both(
        dir,
        name,
        &LineChart {
            title,
            axes,
            series,
            marks,
            x_max,
            y_max,
        },
    )
}

/// A value with its interval: (mean, low, high).
pub type Estimate = (f64, f64, f64);

/// Categories along x (link profiles, …), each series a mean with its
/// interval per category (a whisker), side by side and not joined: the
/// categories are no continuous axis.
pub fn intervals(
    dir: &Path,
    name: &str,
    title: &str,
    (x_desc, y_desc): (&str, &str),
    categories: &[String],
    series: &[(String, RGBColor, Vec<Option<Estimate>>)],
) -> Result<PathBuf> {
    struct Whiskers<'a> {
        title: &'a str,
        axes: (&'a str, &'a str),
        categories: &'a [String],
        series: &'a [(String, RGBColor, Vec<Option<Estimate>>)],
    }
    impl Picture for Whiskers<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let Whiskers {
                title,
                axes,
                categories,
                series,
            } = self;
            let top = series
                .iter()
                .flat_map(|(_, _, v)| v.iter().flatten().map(|e| e.2))
                .fold(0.0f64, f64::max)
                .max(1e-3)
                * 1.15;
            let n = categories.len().max(1);
            root.fill(&WHITE).map_err(err)?;
            let mut chart = ChartBuilder::on(root)
                .caption(*title, (FONT, 20))
                .margin(12)
                .x_label_area_size(36)
                .y_label_area_size(52)
                .build_cartesian_2d(-0.5..n as f64 - 0.5, 0.0..top)
                .map_err(err)?;
            let label = |x: &f64| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    categories.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            };
            chart
                .configure_mesh()
                .x_labels(n * 2 + 1)
                .x_label_formatter(&label)
                .disable_x_mesh()
                .x_desc(axes.0)
                .y_desc(axes.1)
                .label_style((FONT, 13))
                .draw()
                .map_err(err)?;
            let k = series.len().max(1) as f64;
            for (s, (name, colour, values)) in series.iter().enumerate() {
                let colour = *colour;
                let dx = (s as f64 - (k - 1.0) / 2.0) * 0.12;
                let at = |i: usize| i as f64 + dx;
                chart
                    .draw_series(values.iter().enumerate().filter_map(|(i, e)| {
                        e.map(|(_, lo, hi)| {
                            PathElement::new(vec![(at(i), lo), (at(i), hi)], colour.stroke_width(2))
                        })
                    }))
                    .map_err(err)?;
                chart
                    .draw_series(values.iter().enumerate().filter_map(|(i, e)| {
                        e.map(|(mean, _, _)| Circle::new((at(i), mean), 5, colour.filled()))
                    }))
                    .map_err(err)?
                    .label(name.as_str())
                    .legend(move |(x, y)| Circle::new((x + 9, y), 5, colour.filled()));
            }
            legend(&mut chart, SeriesLabelPosition::UpperLeft)
        }
    }
    both(
        dir,
        name,
        &Whiskers {
            title,
            axes: (x_desc, y_desc),
            categories,
            series,
        },
    )
}

/// The planned path and the paths the robot truly took, on the arena's
/// floor with its obstacles, to scale.
pub fn paths(
    dir: &Path,
    name: &str,
    title: &str,
    arena: &Arena,
    planned: &[Point],
    taken: &[(String, RGBColor, Vec<Point>)],
) -> Result<PathBuf> {
    struct Paths<'a> {
        title: &'a str,
        arena: &'a Arena,
        planned: &'a [Point],
        taken: &'a [(String, RGBColor, Vec<Point>)],
    }
    impl Picture for Paths<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let Paths {
                title,
                arena,
                planned,
                taken,
            } = self;
            let floor = (arena.width_mm, arena.height_mm);
            let mut chart = chart(root, title, floor, ("x, mm", "y, mm"))?;
            let xy = |p: &Point| (p.x_mm, p.y_mm);
            let obstacle = OBSTACLE.filled();
            for o in &arena.obstacles {
                let outline: Vec<(f64, f64)> = match &o.shape {
                    Shape::Rect {
                        x_mm,
                        y_mm,
                        width_mm,
                        height_mm,
                    } => vec![
                        (*x_mm, *y_mm),
                        (x_mm + width_mm, *y_mm),
                        (x_mm + width_mm, y_mm + height_mm),
                        (*x_mm, y_mm + height_mm),
                    ],
                    Shape::Circle {
                        x_mm,
                        y_mm,
                        radius_mm,
                    } => (0..48)
                        .map(|i| {
                            let a = std::f64::consts::TAU * f64::from(i) / 48.0;
                            (x_mm + radius_mm * a.cos(), y_mm + radius_mm * a.sin())
                        })
                        .collect(),
                    Shape::Polygon { points } => points.iter().map(xy).collect(),
                };
                chart
                    .draw_series(std::iter::once(Polygon::new(outline, obstacle)))
                    .map_err(err)?;
            }
            chart
                .draw_series(LineSeries::new(
                    planned.iter().map(xy),
                    PLANNED.stroke_width(6),
                ))
                .map_err(err)?
                .label("planned")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], PLANNED.stroke_width(6))
                });
            for (label, colour, path) in taken.iter() {
                let colour = *colour;
                chart
                    .draw_series(LineSeries::new(path.iter().map(xy), colour.stroke_width(2)))
                    .map_err(err)?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
            }
            legend(&mut chart, SeriesLabelPosition::UpperRight)
        }
    }
    // The floor to scale: the plot's area as wide for its height as the
    // floor (the axes' labels and the title around it).
    let width = SIZE.0;
    let area = f64::from(width - AXES_PX.0) / arena.width_mm.max(1.0);
    let height = (arena.height_mm * area).round().clamp(100.0, 2000.0) as u32 + AXES_PX.1;
    both_sized(
        dir,
        name,
        &Paths {
            title,
            arena,
            planned,
            taken,
        },
        (width, height),
    )
}
