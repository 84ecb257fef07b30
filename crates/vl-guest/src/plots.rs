//! The report's pictures, drawn once as SVG and once as PNG with `plotters`
//! (its text in the Ubuntu font egui already ships, so nothing is needed
//! from the system).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use vl_core::Point;

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
    font();
    let svg = dir.join(format!("{name}.svg"));
    let png = dir.join(format!("{name}.png"));
    {
        let root = SVGBackend::new(&svg, SIZE).into_drawing_area();
        picture.draw(&root)?;
        root.present().map_err(|e| draw_error(&svg, e))?;
    }
    {
        let root = BitMapBackend::new(&png, SIZE).into_drawing_area();
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

/// Lines of (x, y) points, one per labelled series.
pub fn lines(
    dir: &Path,
    name: &str,
    title: &str,
    axes: (&str, &str),
    series: &[Series],
    points: bool,
) -> Result<PathBuf> {
    let xs = series.iter().flat_map(|(_, _, v)| v.iter().map(|p| p.0));
    let ys = series.iter().flat_map(|(_, _, v)| v.iter().map(|p| p.1));
    let x_max = xs.fold(0.0f64, f64::max).max(1e-3) * 1.05;
    let y_max = ys.fold(0.0f64, f64::max).max(1e-3) * 1.1;
    struct LineChart<'a> {
        title: &'a str,
        axes: (&'a str, &'a str),
        series: &'a [Series],
        points: bool,
        x_max: f64,
        y_max: f64,
    }
    impl Picture for LineChart<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let LineChart {
                title,
                axes,
                series,
                points,
                x_max,
                y_max,
            } = self;
            let (x_max, y_max, points) = (*x_max, *y_max, *points);
            let mut chart = chart(root, title, (x_max, y_max), *axes)?;
            for (label, colour, data) in series.iter() {
                let colour = *colour;
                chart
                    .draw_series(LineSeries::new(
                        data.iter().copied(),
                        colour.stroke_width(2),
                    ))
                    .map_err(err)?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                    });
                if points {
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
            points,
            x_max,
            y_max,
        },
    )
}

/// The planned path and the paths the robot truly took, on the arena's floor.
pub fn paths(
    dir: &Path,
    name: &str,
    title: &str,
    floor_mm: (f64, f64),
    planned: &[Point],
    taken: &[(String, RGBColor, Vec<Point>)],
) -> Result<PathBuf> {
    struct Paths<'a> {
        title: &'a str,
        floor_mm: (f64, f64),
        planned: &'a [Point],
        taken: &'a [(String, RGBColor, Vec<Point>)],
    }
    impl Picture for Paths<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
            let Paths {
                title,
                floor_mm,
                planned,
                taken,
            } = self;
            let mut chart = chart(root, title, *floor_mm, ("x, mm", "y, mm"))?;
            let xy = |p: &Point| (p.x_mm, p.y_mm);
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
    both(
        dir,
        name,
        &Paths {
            title,
            floor_mm,
            planned,
            taken,
        },
    )
}
