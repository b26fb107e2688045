//! The report's plots: each one an SVG document in a string, drawn by `plotters`.
//!
//! Contract: every plot starts with its title (the first `<text>` of the SVG), has an x axis in
//! bus seconds unless it is the latency plot, and draws each series as one line with one point
//! per value it has. Text is escaped by the SVG backend, and characters XML 1.0 cannot carry (in
//! node names, say) become U+FFFD. A plot that cannot be drawn gives an
//! error message, not a panic.

use crate::scenario::Series;
use crate::scenario::series::{ClassLatency, Sample};
use plotters::coord::Shift;
use plotters::prelude::*;

/// Plot size, px.
const SIZE: (u32, u32) = (760, 300);
const FONT: &str = "sans-serif";

/// Plot titles, in the order the report shows them.
pub const LOAD: &str = "Bus load per second";
/// See [`LOAD`].
pub const LATENCY: &str = "Queueing latency per priority class";
/// See [`LOAD`].
pub const COUNTERS: &str = "Error counters per node (TEC, REC)";
/// See [`LOAD`].
pub const YIELD: &str = "Yield";
/// See [`LOAD`].
pub const SPEED: &str = "Travel speed";

type Result<T> = std::result::Result<T, String>;

fn err(e: impl std::fmt::Display) -> String {
    e.to_string()
}

/// Draws into a titled SVG of [`SIZE`] and returns the SVG text.
fn svg(
    title: &str,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<()>,
) -> Result<String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let area = root.titled(title, (FONT, 18)).map_err(err)?;
        draw(&area)?;
        root.present().map_err(err)?;
    }
    Ok(crate::scenario::junit::xml_text(&out))
}

/// Upper end of a y axis that shows `max` with some room, never an empty range.
fn top(max: f64, at_least: f64) -> f64 {
    if max.is_finite() {
        (max * 1.1).max(at_least)
    } else {
        at_least
    }
}

/// One series of a line chart.
type Line<'a> = (&'a str, RGBColor, Vec<(f64, f64)>);

/// One line chart over bus seconds; `legend` names the series.
fn lines(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    end_s: f64,
    (y_desc, y_top): (&str, f64),
    series: Vec<Line<'_>>,
    legend: bool,
) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..end_s.max(1.0), 0f64..y_top)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("bus time [s]")
        .y_desc(y_desc)
        .draw()
        .map_err(err)?;
    for (label, colour, points) in series {
        let drawn = chart
            .draw_series(LineSeries::new(points, colour.stroke_width(2)))
            .map_err(err)?;
        if legend {
            drawn
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

/// Bus load of each 1 s window, %.
pub fn load(s: &Series) -> Result<String> {
    let points: Vec<(f64, f64)> = s.load.iter().map(|(t, l)| (*t, l * 100.0)).collect();
    svg(LOAD, SIZE, |area| {
        lines(
            area,
            s.end_s,
            ("load [%]", 100.0),
            vec![("load", BLUE, points)],
            false,
        )
    })
}

/// One kind of bar of the latency plot: label, colour, half width, value in µs.
type Bar = (&'static str, RGBColor, f64, fn(&ClassLatency) -> f64);

/// Mean, 99th percentile and maximum latency (submit to end of frame) of each priority class,
/// as nested bars.
pub fn latency(s: &Series) -> Result<String> {
    svg(LATENCY, SIZE, |area| {
        let n = s.latency.len();
        let y_top = top(s.latency.iter().map(|c| c.max_us / 1e3).fold(0.0, f64::max), 1.0);
        let classes: Vec<String> = s.latency.iter().map(|c| c.class.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-0.5f64..(n.max(1) as f64 - 0.5), 0f64..y_top)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n.max(1))
            .x_label_formatter(&|x| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    classes.get(i as usize).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .x_desc("priority class")
            .y_desc("latency [ms]")
            .draw()
            .map_err(err)?;
        // Widest first, so that each narrower bar stays visible on top of the one behind it.
        let bars: [Bar; 3] = [
            ("max", RGBColor(190, 200, 235), 0.4, |c| c.max_us),
            ("p99", RGBColor(90, 120, 210), 0.27, |c| c.p99_us),
            ("mean", RGBColor(20, 40, 120), 0.14, |c| c.mean_us),
        ];
        for (label, colour, half, value) in bars {
            chart
                .draw_series(s.latency.iter().enumerate().map(|(i, c)| {
                    let x = i as f64;
                    Rectangle::new([(x - half, 0.0), (x + half, value(c) / 1e3)], colour.filled())
                }))
                .map_err(err)?
                .label(label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], colour.filled()));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
        Ok(())
    })
}

/// TEC (upper panel) and REC (lower panel) of every node whose counters rose, as steps; the
/// node names in a column on the right (a receive error raises every receiver's REC, so the list
/// is often long).
pub fn counters(s: &Series) -> Result<String> {
    svg(COUNTERS, (SIZE.0, SIZE.1 * 2 - 40), |area| {
        let (plots, names) = area.split_horizontally(area.dim_in_pixel().0 - 90);
        let (upper, lower) = plots.split_vertically(plots.dim_in_pixel().1 / 2);
        // Hues spread evenly (short of a full turn, so the last is not the first), dark enough to see
        // on white.
        let n = s.counters.len().max(1) as f64;
        let colour = |i: usize| {
            let c = HSLColor(0.85 * i as f64 / n, 0.8, 0.38).to_backend_color();
            RGBColor(c.rgb.0, c.rgb.1, c.rgb.2)
        };
        for (panel, name, pick) in [
            (
                &upper,
                "TEC",
                (|p: &(f64, u16, u16)| p.1) as fn(&(f64, u16, u16)) -> u16,
            ),
            (&lower, "REC", |p| p.2),
        ] {
            let steps: Vec<Line<'_>> = s
                .counters
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let mut points = vec![(0.0, 0.0)];
                    for p in &n.points {
                        let last = points.last().map_or(0.0, |l| l.1);
                        points.push((p.0, last));
                        points.push((p.0, f64::from(pick(p))));
                    }
                    (n.node.as_str(), colour(i), points)
                })
                .collect();
            let max = steps
                .iter()
                .flat_map(|(_, _, p)| p.iter().map(|x| x.1))
                .fold(0.0, f64::max);
            lines(panel, s.end_s, (name, top(max, 10.0)), steps, false)?;
        }
        if s.counters.is_empty() {
            upper
                .draw(&Text::new(
                    "no error counter rose above zero",
                    (80, 40),
                    (FONT, 14),
                ))
                .map_err(err)?;
        }
        for (i, n) in s.counters.iter().enumerate() {
            let y = 30 + 18 * i as i32;
            names
                .draw(&PathElement::new(
                    vec![(5, y), (25, y)],
                    colour(i).stroke_width(2),
                ))
                .map_err(err)?;
            names
                .draw(&Text::new(n.node.as_str(), (30, y - 6), (FONT, 12)))
                .map_err(err)?;
        }
        Ok(())
    })
}

/// The monitor's yield against the plant's true harvested mass, kg.
pub fn yield_kg(s: &Series) -> Result<String> {
    let truth = ("plant: harvested", RGBColor(0, 120, 0));
    let shown = ("monitor: yield", RGBColor(200, 90, 0));
    truth_and_shown(s, YIELD, "mass [kg]", truth, shown, |x| {
        (x.harvested_kg, x.monitor_kg)
    })
}

/// The plant's true travel speed against what the monitor shows, km/h.
pub fn speed(s: &Series) -> Result<String> {
    let truth = ("plant: actual", BLUE);
    let shown = ("monitor: shown", RGBColor(200, 90, 0));
    truth_and_shown(s, SPEED, "speed [km/h]", truth, shown, |x| {
        (x.speed_kmh, x.monitor_speed_kmh)
    })
}

/// One plant value against what the monitor shows of it, over time.
fn truth_and_shown(
    s: &Series,
    title: &str,
    axis: &str,
    truth: (&str, RGBColor),
    shown: (&str, RGBColor),
    value: impl Fn(&Sample) -> (f64, Option<f64>),
) -> Result<String> {
    let plant: Vec<(f64, f64)> = s.samples.iter().map(|x| (x.t_s, value(x).0)).collect();
    let monitor: Vec<(f64, f64)> = s
        .samples
        .iter()
        .filter_map(|x| Some((x.t_s, value(x).1?)))
        .collect();
    let max = plant.iter().chain(&monitor).map(|p| p.1).fold(0.0, f64::max);
    svg(title, SIZE, |area| {
        lines(
            area,
            s.end_s,
            (axis, top(max, 1.0)),
            vec![(truth.0, truth.1, plant), (shown.0, shown.1, monitor)],
            true,
        )
    })
}
