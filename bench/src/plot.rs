//! The speed-against-error plot (SVG): max relative t error (log, floored at 1e-17) against
//! ns per ray (log), one colour per primitive, its Pareto front as a line, the default method
//! ringed, parry3d as crosses.

use crate::cases::Row;
use plotters::prelude::*;
use std::path::Path;

const FLOOR: f64 = 1e-17;

const COLOURS: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(23, 190, 207),
];

fn error(r: &Row) -> f64 {
    r.m.max_rel_t.max(FLOOR)
}

/// Non-dominated points (faster or more accurate than every other), by increasing time.
fn pareto(points: &mut [(f64, f64)]) -> Vec<(f64, f64)> {
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for &(x, y) in points.iter() {
        if y < best {
            front.push((x, y));
            best = y;
        }
    }
    front
}

pub fn speed_vs_error(rows: &[Row], path: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1100, 720)).into_drawing_area();
    root.fill(&WHITE)?;
    let x_max = rows.iter().map(|r| r.m.ns_median).fold(10.0, f64::max) * 1.5;
    let x_min = rows
        .iter()
        .map(|r| r.m.ns_median)
        .fold(f64::INFINITY, f64::min)
        .max(0.1)
        / 1.5;
    let y_max = rows.iter().map(error).fold(1e-15, f64::max) * 10.0;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "zeroset: max relative t error against ns/ray (one thread; lines: Pareto fronts; ring: default; ×: parry3d)",
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .right_y_label_area_size(10)
        .build_cartesian_2d((x_min..x_max).log_scale(), (FLOOR / 2.0..y_max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("ns per ray (median over passes; hits and misses mixed)")
        .y_desc("max relative t error (1e-17 = exact)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()?;
    let mut primitives: Vec<&str> = rows.iter().map(|r| r.primitive).collect();
    primitives.dedup();
    for (i, p) in primitives.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let own: Vec<&Row> = rows
            .iter()
            .filter(|r| r.primitive == *p && r.family != "parry3d")
            .collect();
        let mut pts: Vec<(f64, f64)> = own.iter().map(|r| (r.m.ns_median, error(r))).collect();
        let front = pareto(&mut pts);
        chart
            .draw_series(LineSeries::new(front, colour.stroke_width(2)))?
            .label(*p)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
        chart.draw_series(
            own.iter()
                .map(|r| Circle::new((r.m.ns_median, error(r)), 3, colour.filled())),
        )?;
        chart.draw_series(
            own.iter()
                .filter(|r| r.default)
                .map(|r| Circle::new((r.m.ns_median, error(r)), 9, colour.stroke_width(2))),
        )?;
        chart.draw_series(
            rows.iter()
                .filter(|r| r.primitive == *p && r.family == "parry3d")
                .map(|r| Cross::new((r.m.ns_median, error(r)), 6, colour.stroke_width(2))),
        )?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
