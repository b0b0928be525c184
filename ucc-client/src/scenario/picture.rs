//! The per-iteration picture of a scenario: the map's solids seen from above, the coverage
//! heat map (how long each cell was under a footprint), the victims (found or missed), the
//! UAVs' and targets' paths, the fire's perimeter at the start and the end, the relay's
//! endpoints with the link's history as a strip, and the pads. SVG and PNG.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::engine::Outcome;
use super::spec::Scenario;
use crate::picture::{MapGeometry, PictureError, VICTIM_COLOUR, write_both};

const SIDE: u32 = 760;
const STRIP: u32 = 60;
/// The band under the map with the iteration's figures.
const FOOTER: u32 = 44;

/// Colours of the UAVs' paths, by index.
const UAV_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

/// Draws `outcome` of `scenario` on `map` into `<base>.svg` and `<base>.png`.
pub fn write(
    scenario: &Scenario,
    map: &MapGeometry,
    outcome: &Outcome,
    iteration: usize,
    base: &Path,
) -> Result<[PathBuf; 2], PictureError> {
    let strip = if outcome.link.is_empty() { 0 } else { STRIP };
    write_both(
        base,
        (SIDE, SIDE + FOOTER + strip),
        |a| draw(scenario, map, outcome, iteration, a),
        |a| draw(scenario, map, outcome, iteration, a),
    )
}

/// The square shown, in chart coordinates (east, north).
fn extent(scenario: &Scenario, outcome: &Outcome) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let mut pts: Vec<[f64; 2]> = Vec::new();
    for t in outcome.tracks.iter().chain(&outcome.target_tracks) {
        pts.extend(t.iter().map(|p| [p[0], p[1]]));
    }
    if let Some(s) = &scenario.search {
        pts.extend(s.area);
    }
    if let Some(r) = &scenario.relay {
        pts.extend(r.endpoints.iter().map(|p| [p[0], p[1]]));
    }
    if let (Some(f), Some(r)) = (scenario.fire, outcome.fire_radius) {
        pts.push([f.center[0] - r, f.center[1] - r]);
        pts.push([f.center[0] + r, f.center[1] + r]);
    }
    if let Some(b) = &scenario.base {
        pts.push([b.location[0], b.location[1]]);
    }
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in pts.iter().filter(|p| p[0].is_finite() && p[1].is_finite()) {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0] > hi[0] {
        (lo, hi) = ([0.0; 2], [0.0; 2]);
    }
    let half = ((hi[0] - lo[0]).max(hi[1] - lo[1]) * 1.1 / 2.0 + 1.0).max(3.0);
    let c = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    (c[1] - half..c[1] + half, c[0] - half..c[0] + half)
}

fn draw<DB: DrawingBackend>(
    scenario: &Scenario,
    map: &MapGeometry,
    outcome: &Outcome,
    iteration: usize,
    root: DrawingArea<DB, Shift>,
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let (top, rest) = root.split_vertically(SIDE);
    let (footer, bottom) = rest.split_vertically(FOOTER);
    let bottom = (!outcome.link.is_empty()).then_some(bottom);
    let figures: Vec<String> = outcome
        .metrics
        .values
        .iter()
        .filter_map(|(n, v)| v.map(|v| format!("{n} {}", short(v))))
        .collect();
    // Iteration 0: the overlay of a run (`outcome.seed` then counts its iterations).
    let title = if iteration == 0 {
        format!(
            "{} · overlay of {} iterations (means)",
            scenario.name, outcome.seed
        )
    } else {
        format!(
            "{} · iteration {} · seed {}",
            scenario.name, iteration, outcome.seed
        )
    };
    let (east, north) = extent(scenario, outcome);
    let mut chart = ChartBuilder::on(&top)
        .caption(&title, ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(east.clone(), north.clone())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("east (m)")
        .y_desc("north (m)")
        .light_line_style(RGBColor(238, 238, 238))
        .draw()
        .map_err(err)?;
    // Coverage heat map.
    if let Some(grid) = &outcome.coverage {
        let max = grid.seen.iter().copied().max().unwrap_or(1).max(1) as f64;
        let [nx, ny] = grid.shape;
        let cells = (0..nx)
            .flat_map(|i| (0..ny).map(move |j| (i, j)))
            .map(|(i, j)| {
                let n = grid.seen[i * ny + j];
                let x = grid.origin[0] + i as f64 * grid.cell;
                let y = grid.origin[1] + j as f64 * grid.cell;
                let colour = if n == 0 {
                    RGBColor(255, 225, 225)
                } else {
                    let f = (n as f64 / max).sqrt();
                    RGBColor(
                        (210.0 - 150.0 * f) as u8,
                        (240.0 - 80.0 * f) as u8,
                        (210.0 - 150.0 * f) as u8,
                    )
                };
                Rectangle::new([(y, x), (y + grid.cell, x + grid.cell)], colour.filled())
            });
        chart.draw_series(cells).map_err(err)?;
        if let Some(s) = &scenario.search {
            let [[x0, y0], [x1, y1]] = s.area;
            chart
                .draw_series([Rectangle::new([(y0, x0), (y1, x1)], BLACK.stroke_width(1))])
                .map_err(err)?
                .label("search area (green: seen, red: never)")
                .legend(|(x, y)| {
                    Rectangle::new(
                        [(x, y - 5), (x + 14, y + 5)],
                        RGBColor(120, 200, 120).filled(),
                    )
                });
        }
    }
    // Solids (not the ground: a slab whose top is at the ground or below).
    let solid = RGBColor(120, 120, 120);
    chart
        .draw_series(map.footprints.iter().filter(|f| f.z_min < -0.05).map(|f| {
            Polygon::new(
                f.outline.iter().map(|&(x, y)| (y, x)).collect::<Vec<_>>(),
                solid.mix(0.55).filled(),
            )
        }))
        .map_err(err)?;
    // Fire.
    if let (Some(f), Some(r_end)) = (scenario.fire, outcome.fire_radius) {
        let circle = |r: f64| {
            (0..=90).map(move |k| {
                let a = std::f64::consts::TAU * k as f64 / 90.0;
                (f.center[1] + r * a.sin(), f.center[0] + r * a.cos())
            })
        };
        chart
            .draw_series(LineSeries::new(
                circle(f.radius),
                RGBColor(255, 170, 60).stroke_width(2),
            ))
            .map_err(err)?
            .label("fire perimeter at the start")
            .legend(|(x, y)| {
                PathElement::new(
                    [(x, y), (x + 14, y)],
                    RGBColor(255, 170, 60).stroke_width(2),
                )
            });
        chart
            .draw_series(LineSeries::new(
                circle(r_end),
                RGBColor(220, 60, 20).stroke_width(2),
            ))
            .map_err(err)?
            .label("fire perimeter at the end")
            .legend(|(x, y)| {
                PathElement::new([(x, y), (x + 14, y)], RGBColor(220, 60, 20).stroke_width(2))
            });
    }
    // Pads and endpoints.
    let pads = scenario.base.iter().map(|p| (p, "base pad")).chain(
        scenario
            .delivery
            .iter()
            .flat_map(|d| [(&d.pickup, "pickup pad"), (&d.dropoff, "drop-off pad")]),
    );
    for (pad, label) in pads {
        chart
            .draw_series([Circle::new(
                (pad.location[1], pad.location[0]),
                6,
                BLACK.stroke_width(2),
            )])
            .map_err(err)?;
        chart
            .draw_series([Text::new(
                label.to_owned(),
                (pad.location[1], pad.location[0]),
                ("sans-serif", 13),
            )])
            .map_err(err)?;
    }
    if let Some(r) = &scenario.relay {
        chart
            .draw_series(r.endpoints.iter().map(|p| {
                Rectangle::new(
                    [(p[1] - 1.0, p[0] - 1.0), (p[1] + 1.0, p[0] + 1.0)],
                    BLUE.filled(),
                )
            }))
            .map_err(err)?
            .label("relay endpoints")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], BLUE.filled()));
    }
    // Paths.
    // The overlay holds the UAVs' paths of several iterations, one after the other.
    let uavs = scenario.uav_count().max(1);
    for (k, t) in outcome.tracks.iter().enumerate() {
        let i = k % uavs;
        let c = UAV_COLOURS[i % UAV_COLOURS.len()];
        let s = chart
            .draw_series(LineSeries::new(
                t.iter().map(|p| (p[1], p[0])),
                c.mix(if iteration == 0 { 0.5 } else { 1.0 })
                    .stroke_width(2),
            ))
            .map_err(err)?;
        if k < uavs && i < 8 {
            s.label(format!("UAV{}", i + 1))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 14, y)], c.stroke_width(2)));
        }
    }
    for (j, t) in outcome.target_tracks.iter().enumerate() {
        let s = chart
            .draw_series(LineSeries::new(
                t.iter().map(|p| (p[1], p[0])),
                RED.stroke_width(3),
            ))
            .map_err(err)?;
        if j == 0 {
            s.label("target")
                .legend(|(x, y)| PathElement::new([(x, y), (x + 14, y)], RED.stroke_width(3)));
        }
    }
    // Victims.
    let found: Vec<_> = outcome
        .victims
        .iter()
        .filter(|(_, t)| t.is_some())
        .collect();
    let missed: Vec<_> = outcome
        .victims
        .iter()
        .filter(|(_, t)| t.is_none())
        .collect();
    if !found.is_empty() {
        chart
            .draw_series(found.iter().map(|(v, _)| {
                Cross::new(
                    (v.center[1], v.center[0]),
                    7,
                    RGBColor(0, 140, 0).stroke_width(3),
                )
            }))
            .map_err(err)?
            .label("victim found")
            .legend(|(x, y)| Cross::new((x + 7, y), 5, RGBColor(0, 140, 0).stroke_width(3)));
    }
    if !missed.is_empty() {
        chart
            .draw_series(missed.iter().map(|(v, _)| {
                Cross::new((v.center[1], v.center[0]), 7, VICTIM_COLOUR.stroke_width(3))
            }))
            .map_err(err)?
            .label("victim missed")
            .legend(|(x, y)| Cross::new((x + 7, y), 5, VICTIM_COLOUR.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    // The figures, two lines under the map.
    let (half_a, half_b) = figures.split_at(figures.len().div_ceil(2));
    for (k, line) in [half_a.join("   "), half_b.join("   ")].iter().enumerate() {
        footer
            .draw(&Text::new(
                line.clone(),
                (20, 4 + 18 * k as i32),
                ("sans-serif", 14),
            ))
            .map_err(err)?;
    }
    // The link's history.
    if let Some(strip) = bottom {
        let end = outcome.metrics.get("time_s").unwrap_or(1.0).max(1e-3);
        let mut chart = ChartBuilder::on(&strip)
            .margin_left(64)
            .margin_right(14)
            .x_label_area_size(22)
            .build_cartesian_2d(0.0..end, 0.0..1.0)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_y_mesh()
            .disable_y_axis()
            .x_desc("link between the endpoints over time (s): green up, red down")
            .draw()
            .map_err(err)?;
        let spans = outcome.link.iter().enumerate().map(|(k, &(t, up))| {
            let t1 = outcome.link.get(k + 1).map_or(end, |n| n.0);
            Rectangle::new(
                [(t, 0.0), (t1, 1.0)],
                if up {
                    RGBColor(60, 170, 60).filled()
                } else {
                    RGBColor(220, 50, 40).filled()
                },
            )
        });
        chart.draw_series(spans).map_err(err)?;
    }
    root.present().map_err(err)
}

fn short(v: f64) -> String {
    if v == v.trunc() && v.abs() < 1e9 {
        format!("{v:.0}")
    } else if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}
