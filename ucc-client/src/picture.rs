//! The map picture of the original map window: the map's walls and obstacles (or what the
//! laser saw), the paths seen from above (x north up, y east right), the waypoints as red
//! squares numbered in the order flown, the start, axes in metres and a scale bar; and the plots of an iteration: a
//! side view (altitude) and altitude, speed and battery over time. Written as SVG and PNG.
//!
//! PNG text is drawn with the DejaVu Sans font embedded in the crate
//! (`assets/DejaVuSans.ttf`, Bitstream Vera license in `assets/DejaVuSans-LICENSE.txt`), so no
//! system font is needed.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::geometry::Coordinates;
use crate::record::TrajectoryPoint;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Side of the square plotting area, pixels.
const PLOT_SIDE: u32 = 700;
const MARGIN: u32 = 20;
const X_LABELS: u32 = 50;
const Y_LABELS: u32 = 60;
const CAPTION: u32 = 40;

/// Paths of more iterations than this share one legend entry (and one colour).
pub(crate) const LEGEND_ITERATIONS: usize = 8;

/// The colours of the paths of a few iterations: dark enough on white, none red (the
/// waypoints) or green (the start), none yellow.
const PATH_COLOURS: [RGBColor; LEGEND_ITERATIONS] = [
    RGBColor(31, 119, 180),  // blue
    RGBColor(255, 127, 14),  // orange
    RGBColor(148, 103, 189), // purple
    RGBColor(23, 190, 207),  // cyan
    RGBColor(140, 86, 75),   // brown
    RGBColor(227, 119, 194), // pink
    RGBColor(90, 90, 90),    // grey
    RGBColor(20, 40, 120),   // navy
];

/// The outline of one solid of the map seen from above, and its height range: what the
/// pictures draw of a map.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// Corners in order, world frame: (x north, y east), metres.
    pub outline: Vec<(f64, f64)>,
    /// The lowest z (z down: the top of the solid is `z_min`), metres.
    pub z_min: f64,
    /// The highest z (the bottom of the solid), metres.
    pub z_max: f64,
}

/// The walls and obstacles of a map, for the pictures (a local server knows them from its map
/// file; a real USARSim reports none, and then the pictures draw the laser's hits instead).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MapGeometry {
    /// Every solid (the map's victims and objects too).
    pub footprints: Vec<Footprint>,
    /// The victims (also in `footprints`), drawn in their own colour with their names.
    pub victims: Vec<Victim>,
}

/// A victim of the map, for the pictures and the browser's map.
#[derive(Debug, Clone, PartialEq)]
pub struct Victim {
    /// Its name (`Victim1`), as USARTruth lists it.
    pub name: String,
    /// `FemaleVictim` or `MaleVictim`.
    pub class: String,
    /// Its body seen from above.
    pub footprint: Footprint,
}

/// The colour of victims in the pictures (and, as `VICTIM_COLOR`, on the browser's map).
pub const VICTIM_COLOUR: RGBColor = RGBColor(214, 40, 200);

impl MapGeometry {
    /// What is wrong with flying at `p` (world frame, z down), if anything: it lies inside a
    /// solid, or below the floor (lower than every solid of the map). Mesh triangles (three
    /// corners) are surfaces, not solids, and are not looked at.
    pub fn problem_at(&self, p: &Coordinates) -> Option<String> {
        let bottom = self
            .footprints
            .iter()
            .map(|f| f.z_max)
            .fold(f64::MIN, f64::max);
        if !self.footprints.is_empty() && p.z >= bottom {
            return Some(format!(
                "is below the floor (nothing of the map lies lower than z = {bottom:.2})"
            ));
        }
        let inside = self.footprints.iter().any(|f| {
            f.outline.len() > 3 && f.z_min < p.z && p.z < f.z_max && encloses(&f.outline, p)
        });
        inside.then(|| "is inside a wall or an obstacle".to_owned())
    }
}

/// Whether the polygon `outline` (x, y) holds the point's x, y (even-odd rule).
fn encloses(outline: &[(f64, f64)], p: &Coordinates) -> bool {
    let mut inside = false;
    for (i, &(x0, y0)) in outline.iter().enumerate() {
        let (x1, y1) = outline[(i + 1) % outline.len()];
        if (y0 > p.y) != (y1 > p.y) && p.x < x0 + (p.y - y0) / (y1 - y0) * (x1 - x0) {
            inside = !inside;
        }
    }
    inside
}

/// A local server's map as the pictures draw it (with the `local` feature, which brings the
/// simulator).
#[cfg(feature = "local")]
impl From<&usar_server::sim::map::Map> for MapGeometry {
    fn from(map: &usar_server::sim::map::Map) -> Self {
        let placed = |p: &usar_server::sim::Placed| Footprint {
            outline: p.outline().iter().map(|q| (q[0], q[1])).collect(),
            z_min: p.center[2] - p.size[2] / 2.0,
            z_max: p.center[2] + p.size[2] / 2.0,
        };
        let mut footprints: Vec<Footprint> = map
            .footprints()
            .into_iter()
            .map(|f| Footprint {
                outline: f.outline.iter().map(|p| (p[0], p[1])).collect(),
                z_min: f.z_min,
                z_max: f.z_max,
            })
            .collect();
        footprints.extend(map.placed().iter().map(placed));
        Self {
            footprints,
            victims: map
                .placed()
                .iter()
                .filter(|p| p.victim)
                .map(|p| Victim {
                    name: p.name.clone(),
                    class: p.class.clone(),
                    footprint: placed(p),
                })
                .collect(),
        }
    }
}

/// What to draw.
#[derive(Debug, Clone, Default)]
pub struct MapPicture {
    /// The caption.
    pub title: String,
    /// One path per iteration (world frame, z ignored).
    pub paths: Vec<Vec<Coordinates>>,
    /// How many iterations flew each path (missing entries: one).
    pub repeats: Vec<usize>,
    /// The waypoints.
    pub waypoints: Vec<Coordinates>,
    /// The start position.
    pub start: Option<Coordinates>,
    /// The map's solids, when known.
    pub geometry: Option<MapGeometry>,
    /// Where the laser hit something (drawn as grey dots).
    pub laser_hits: Vec<Coordinates>,
}

/// A picture that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw {path}: {message}")]
pub struct PictureError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub message: String,
}

/// Draws `draw` into `<base>.svg` and `<base>.png` of `size` pixels; returns their paths.
pub(crate) fn write_both(
    base: &Path,
    size: (u32, u32),
    svg_draw: impl Fn(DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), String>,
    png_draw: impl Fn(DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<[PathBuf; 2], PictureError> {
    let svg = base.with_extension("svg");
    let png = base.with_extension("png");
    let failed = |path: &Path| {
        let path = path.to_owned();
        move |message: String| PictureError { path, message }
    };
    // Both backends measure text with the font.
    register_font().map_err(failed(&svg))?;
    svg_draw(SVGBackend::new(&svg, size).into_drawing_area()).map_err(failed(&svg))?;
    let mut pixels = vec![0; 3 * size.0 as usize * size.1 as usize];
    png_draw(BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area())
        .map_err(failed(&png))?;
    write_png(&png, size, &pixels).map_err(failed(&png))?;
    Ok([svg, png])
}

/// Encodes RGB `pixels` as a PNG file. Fast deflate and one filter for every row: the
/// adaptive filter (five filters tried on every row) took most of the time of a picture.
/// "Paeth" predicts the charts' flat areas and lines from their neighbours: files about the
/// size the adaptive filter gave ("up" or "sub" made them 2.5–3× larger, for ~2 % speed).
fn write_png(path: &Path, (width, height): (u32, u32), pixels: &[u8]) -> Result<(), String> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let file = std::fs::File::create(path).map_err(|e| e.to_string())?;
    let mut out = std::io::BufWriter::new(file);
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Paeth)
        .write_image(pixels, width, height, image::ColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    std::io::Write::flush(&mut out).map_err(|e| e.to_string())
}

impl MapPicture {
    /// Writes `<base>.svg` and `<base>.png`; returns their paths.
    pub fn write(&self, base: &Path) -> Result<[PathBuf; 2], PictureError> {
        let size = (
            PLOT_SIDE + Y_LABELS + 2 * MARGIN,
            PLOT_SIDE + X_LABELS + CAPTION + 2 * MARGIN,
        );
        write_both(base, size, |a| self.draw(a), |a| self.draw(a))
    }

    /// The square region shown, in chart coordinates (east, north): it holds every point of
    /// the paths, the waypoints and the start with a margin, and is at least 4 m wide.
    fn extent(&self) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
        let points = self
            .paths
            .iter()
            .flatten()
            .chain(&self.waypoints)
            .chain(&self.start);
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for p in points.filter(|p| p.x.is_finite() && p.y.is_finite()) {
            lo = (lo.0.min(p.y), lo.1.min(p.x));
            hi = (hi.0.max(p.y), hi.1.max(p.x));
        }
        if lo.0 > hi.0 {
            (lo, hi) = ((0.0, 0.0), (0.0, 0.0));
        }
        let half = ((hi.0 - lo.0).max(hi.1 - lo.1) * 1.15 / 2.0 + 0.5).max(2.0);
        let centre = ((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0);
        (
            centre.0 - half..centre.0 + half,
            centre.1 - half..centre.1 + half,
        )
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let (east, north) = self.extent();
        let mut chart = ChartBuilder::on(&root)
            .caption(&self.title, ("sans-serif", 22))
            .margin(MARGIN)
            .x_label_area_size(X_LABELS)
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(east.clone(), north.clone())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("y, east (m)")
            .y_desc("x, north (m)")
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(err)?;

        let top_view = |p: &Coordinates| (p.y, p.x);
        let inside = |(e, n): (f64, f64)| east.contains(&e) && north.contains(&n);
        // The map first, under everything: solids in grey, or else the laser's hits.
        let wall = RGBColor(150, 150, 150);
        if let Some(geometry) = &self.geometry {
            let clip = (east.start, east.end, north.start, north.end);
            // Only what stands at the flown heights: not the floor, not the ceiling.
            let (low, high) = self
                .paths
                .iter()
                .flatten()
                .chain(&self.waypoints)
                .chain(&self.start)
                .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
                    (lo.min(p.z), hi.max(p.z))
                });
            let at_height = |f: &&Footprint| low > high || (f.z_min <= high && f.z_max >= low);
            let solids: Vec<Vec<(f64, f64)>> = geometry
                .footprints
                .iter()
                .filter(at_height)
                .map(|f| {
                    let outline: Vec<(f64, f64)> = f.outline.iter().map(|&(x, y)| (y, x)).collect();
                    clip_polygon(&outline, clip)
                })
                .filter(|clipped| clipped.len() >= 3)
                .collect();
            // Named in the legend only when some solid is in view.
            if !solids.is_empty() {
                chart
                    .draw_series(
                        solids
                            .into_iter()
                            .map(|points| Polygon::new(points, wall.mix(0.6).filled())),
                    )
                    .map_err(err)?
                    .label("walls and obstacles")
                    .legend(move |(x, y)| {
                        Rectangle::new([(x + 5, y - 5), (x + 15, y + 5)], wall.mix(0.6).filled())
                    });
            }
            // Victims at any height (they lie on the floor), in their colour, named.
            let victims: Vec<(String, Vec<(f64, f64)>)> = geometry
                .victims
                .iter()
                .map(|v| {
                    let outline: Vec<(f64, f64)> =
                        v.footprint.outline.iter().map(|&(x, y)| (y, x)).collect();
                    (v.name.clone(), clip_polygon(&outline, clip))
                })
                .filter(|(_, clipped)| clipped.len() >= 3)
                .collect();
            if !victims.is_empty() {
                chart
                    .draw_series(
                        victims.iter().map(|(_, points)| {
                            Polygon::new(points.clone(), VICTIM_COLOUR.filled())
                        }),
                    )
                    .map_err(err)?
                    .label("victims")
                    .legend(move |(x, y)| {
                        Rectangle::new([(x + 5, y - 5), (x + 15, y + 5)], VICTIM_COLOUR.filled())
                    });
                chart
                    .draw_series(victims.iter().map(|(name, points)| {
                        // Beside the body (east of it), not over it.
                        let n = points.len() as f64;
                        let east = points.iter().map(|p| p.0).fold(f64::MIN, f64::max);
                        let north = points.iter().map(|p| p.1).sum::<f64>() / n;
                        Text::new(
                            name.clone(),
                            (east + 0.1, north),
                            ("sans-serif", 13).into_font().color(&VICTIM_COLOUR),
                        )
                    }))
                    .map_err(err)?;
            }
        } else if !self.laser_hits.is_empty() {
            let hits = self.laser_hits.iter().map(top_view).filter(|p| inside(*p));
            chart
                .draw_series(hits.map(|p| Circle::new(p, 1, wall.filled())))
                .map_err(err)?
                .label("laser hits")
                .legend(move |(x, y)| Circle::new((x + 10, y), 2, wall.filled()));
        }

        let repeats = |i: usize| self.repeats.get(i).copied().unwrap_or(1).max(1);
        let n: usize = (0..self.paths.len()).map(repeats).sum();
        let many = n > LEGEND_ITERATIONS;
        for (i, path) in self.paths.iter().enumerate() {
            // Many paths: one colour, translucent, so that where they agree is darker (a path
            // flown k times as dark as k paths drawn over each other). A few: a colour each,
            // and each later one narrower than the one before, so that paths that agree show
            // as stripes instead of the last one hiding the others.
            let (color, width) = if many {
                let alpha = 1.0 - 0.6f64.powi(repeats(i).min(64) as i32);
                (PATH_COLOURS[0].mix(alpha), 1)
            } else {
                let k = self.paths.len();
                (PATH_COLOURS[i].to_rgba(), 2 + 3 * (k - 1 - i) as u32)
            };
            let series = chart
                .draw_series(LineSeries::new(
                    path.iter().map(top_view),
                    color.stroke_width(width),
                ))
                .map_err(err)?;
            // One legend entry per iteration for a few; one for all of many.
            let label = match (n, many) {
                (1, _) => Some("path".to_owned()),
                (n, true) if i == 0 => Some(format!("paths of {n} iterations")),
                (_, true) => None,
                (_, false) => Some(format!("iteration {}", i + 1)),
            };
            if let Some(label) = label {
                let color = if many {
                    PATH_COLOURS[0].to_rgba()
                } else {
                    color
                };
                series.label(label).legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(3))
                });
            }
        }
        if let Some(start) = &self.start {
            let green = RGBColor(0, 150, 0);
            chart
                .draw_series(std::iter::once(TriangleMarker::new(
                    top_view(start),
                    8,
                    green.filled(),
                )))
                .map_err(err)?
                .label("start")
                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, green.filled()));
        }
        // Waypoints on top of the start: hollow squares, so both stay visible (and in the
        // legend only when there are some).
        if !self.waypoints.is_empty() {
            chart
                .draw_series(self.waypoints.iter().map(|p| {
                    EmptyElement::at(top_view(p))
                        + Rectangle::new([(-6, -6), (6, 6)], RED.stroke_width(3))
                }))
                .map_err(err)?
                .label("waypoint")
                .legend(|(x, y)| {
                    Rectangle::new([(x + 5, y - 5), (x + 15, y + 5)], RED.stroke_width(2))
                });
        }
        // Their numbers, in the order flown (waypoints at one place share a label: "1, 5").
        let font = ("sans-serif", 15).into_font().color(&RED);
        chart
            .draw_series(
                waypoint_labels(&self.waypoints)
                    .into_iter()
                    .map(|(p, label)| {
                        EmptyElement::at(top_view(&p)) + Text::new(label, (9, -22), font.clone())
                    }),
            )
            .map_err(err)?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(err)?;

        // Scale bar: a round length about a fifth of the width, above the plot on the right
        // (outside the data, so it never hides the start or a waypoint).
        let width = east.end - east.start;
        let length = nice_length(width / 5.0);
        let (x0, _) = chart.backend_coord(&(east.start, north.start));
        let (x1, _) = chart.backend_coord(&(east.start + length, north.start));
        let (right, top) = chart.backend_coord(&(east.end, north.end));
        let pixels = x1 - x0;
        let y = top - 12;
        root.draw(&PathElement::new(
            [(right - pixels, y), (right, y)],
            BLACK.stroke_width(3),
        ))
        .map_err(err)?;
        root.draw(&Text::new(
            format!("{length} m"),
            (right - pixels - 50, y - 8),
            ("sans-serif", 14).into_font().color(&BLACK),
        ))
        .map_err(err)?;
        root.present().map_err(err)
    }
}

/// The numbers of the waypoints (1-based), one label per place.
fn waypoint_labels(waypoints: &[Coordinates]) -> Vec<(Coordinates, String)> {
    let mut labels: Vec<(Coordinates, String)> = Vec::new();
    for (i, p) in waypoints.iter().enumerate() {
        let same = |q: &Coordinates| (q.x - p.x).abs() < 0.05 && (q.y - p.y).abs() < 0.05;
        match labels.iter_mut().find(|(q, _)| same(q)) {
            Some((_, label)) => *label = format!("{label}, {}", i + 1),
            None => labels.push((*p, (i + 1).to_string())),
        }
    }
    labels
}

/// The part of a polygon inside a rectangle `(x0, x1, y0, y1)` (Sutherland–Hodgman).
fn clip_polygon(points: &[(f64, f64)], (x0, x1, y0, y1): (f64, f64, f64, f64)) -> Vec<(f64, f64)> {
    let edges: [(usize, f64, bool); 4] =
        [(0, x0, true), (0, x1, false), (1, y0, true), (1, y1, false)];
    let mut out = points.to_vec();
    for (axis, bound, keep_above) in edges {
        let coord = |p: (f64, f64)| if axis == 0 { p.0 } else { p.1 };
        let inside = |p: (f64, f64)| (coord(p) >= bound) == keep_above || coord(p) == bound;
        let input = std::mem::take(&mut out);
        for (i, &p) in input.iter().enumerate() {
            let q = input[(i + 1) % input.len()];
            if inside(p) {
                out.push(p);
            }
            if inside(p) != inside(q) {
                let t = (bound - coord(p)) / (coord(q) - coord(p));
                out.push((p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1)));
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

/// The side view and the time plots of one iteration: altitude over x (north), and altitude,
/// speed, battery, attitude (roll and pitch: the tilt of a vehicle with physics) and the
/// horizontal position (drift) over simulated time.
#[derive(Debug, Clone, Default)]
pub struct Plots {
    /// The caption.
    pub title: String,
    /// The trajectory.
    pub trajectory: Vec<TrajectoryPoint>,
    /// The waypoints (shown in the side view).
    pub waypoints: Vec<Coordinates>,
}

impl Plots {
    /// Writes `<base>.svg` and `<base>.png`; returns their paths.
    pub fn write(&self, base: &Path) -> Result<[PathBuf; 2], PictureError> {
        write_both(base, (1000, 1120), |a| self.draw(a), |a| self.draw(a))
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let root = root.titled(&self.title, ("sans-serif", 22)).map_err(err)?;
        let panels = root.split_evenly((3, 2));
        let t: Vec<f64> = self.trajectory.iter().map(|p| p.time).collect();
        let altitude: Vec<(f64, f64)> = self
            .trajectory
            .iter()
            .map(|p| (p.time, -p.position.z))
            .collect();
        let speed: Vec<(f64, f64)> = self
            .trajectory
            .iter()
            .filter_map(|p| p.velocity.map(|v| (p.time, v.norm())))
            .collect();
        let battery: Vec<(f64, f64)> = self
            .trajectory
            .iter()
            .filter_map(|p| p.battery.map(|b| (p.time, b * 100.0)))
            .collect();
        let side: Vec<(f64, f64)> = self
            .trajectory
            .iter()
            .map(|p| (p.position.x, -p.position.z))
            .collect();
        let waypoints: Vec<(f64, f64)> = self.waypoints.iter().map(|w| (w.x, -w.z)).collect();
        let time_range = range(t.iter().copied(), 1.0);
        line_panel(
            &panels[0],
            "side view: altitude over x",
            ("x, north (m)", "altitude, -z (m)"),
            &[("", &side)],
            &waypoints,
            range(side.iter().chain(&waypoints).map(|p| p.0), 2.0),
        )
        .map_err(err)?;
        line_panel(
            &panels[1],
            "altitude",
            ("simulated time (s)", "altitude, -z (m)"),
            &[("", &altitude)],
            &[],
            time_range.clone(),
        )
        .map_err(err)?;
        line_panel(
            &panels[2],
            "speed",
            ("simulated time (s)", "speed (m/s)"),
            &[("", &speed)],
            &[],
            time_range.clone(),
        )
        .map_err(err)?;
        line_panel(
            &panels[3],
            "battery",
            ("simulated time (s)", "battery (%)"),
            &[("", &battery)],
            &[],
            time_range.clone(),
        )
        .map_err(err)?;
        let attitude = |pick: fn(&Coordinates) -> f64| -> Vec<(f64, f64)> {
            self.trajectory
                .iter()
                .filter_map(|p| p.orientation.map(|o| (p.time, pick(&o).to_degrees())))
                .collect()
        };
        let (roll, pitch) = (attitude(|o| o.x), attitude(|o| o.y));
        line_panel(
            &panels[4],
            "attitude",
            ("simulated time (s)", "angle (deg)"),
            &[("roll", &roll), ("pitch", &pitch)],
            &[],
            time_range.clone(),
        )
        .map_err(err)?;
        let along = |pick: fn(&Coordinates) -> f64| -> Vec<(f64, f64)> {
            self.trajectory
                .iter()
                .map(|p| (p.time, pick(&p.position)))
                .collect()
        };
        let (north, east) = (along(|p| p.x), along(|p| p.y));
        line_panel(
            &panels[5],
            "horizontal position",
            ("simulated time (s)", "position (m)"),
            &[("x, north", &north), ("y, east", &east)],
            &[],
            time_range,
        )
        .map_err(err)?;
        root.present().map_err(err)
    }
}

/// A range around the values with a margin, at least `min_width` wide.
fn range(values: impl Iterator<Item = f64>, min_width: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return 0.0..min_width;
    }
    let pad = ((hi - lo) * 0.05).max((min_width - (hi - lo)).max(0.0) / 2.0);
    lo - pad..hi + pad
}

/// One panel: lines of `(x, y)` points (labelled when there are several), red squares at
/// `marks`.
fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    series: &[(&str, &[(f64, f64)])],
    marks: &[(f64, f64)],
    x: std::ops::Range<f64>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let points = series.iter().flat_map(|(_, points)| points.iter());
    let mut y = range(points.chain(marks).map(|p| p.1), 0.5);
    if series.len() > 1 {
        // Room above the data for the legend, which would otherwise cover it.
        y.end += (y.end - y.start) * 0.4;
    }
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let colours = [BLUE, RGBColor(230, 120, 0)];
    for (i, (label, points)) in series.iter().enumerate() {
        let colour = colours[i % colours.len()];
        let drawn = chart.draw_series(LineSeries::new(
            points.iter().copied(),
            colour.stroke_width(2),
        ))?;
        if series.len() > 1 {
            drawn.label(*label).legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        }
    }
    // The marks (waypoints), numbered in the order flown.
    let font = ("sans-serif", 13).into_font().color(&RED);
    chart.draw_series(marks.iter().enumerate().map(|(i, &p)| {
        EmptyElement::at(p)
            + Rectangle::new([(-5, -5), (5, 5)], RED.stroke_width(2))
            + Text::new((i + 1).to_string(), (7, -19), font.clone())
    }))?;
    if series.len() > 1 {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()?;
    }
    Ok(())
}

/// The largest of 1, 2, 5 × 10ⁿ not above `v` (at least 0.1).
fn nice_length(v: f64) -> f64 {
    let v = v.max(0.1);
    let magnitude = 10f64.powf(v.log10().floor());
    let step = [5.0, 2.0, 1.0]
        .into_iter()
        .find(|m| m * magnitude <= v)
        .unwrap_or(1.0);
    step * magnitude
}

fn register_font() -> Result<(), String> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "the embedded font is invalid".to_owned());
    });
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_in_a_solid_or_under_the_floor_are_named() {
        let room = MapGeometry {
            footprints: vec![
                Footprint {
                    outline: vec![(-10.0, -10.0), (10.0, -10.0), (10.0, 10.0), (-10.0, 10.0)],
                    z_min: 0.0,
                    z_max: 0.2,
                },
                Footprint {
                    outline: vec![(4.0, -1.0), (5.0, -1.0), (5.0, 1.0), (4.0, 1.0)],
                    z_min: -3.0,
                    z_max: 0.0,
                },
            ],
            victims: Vec::new(),
        };
        let at = |x, y, z| room.problem_at(&Coordinates::new(x, y, z));
        assert_eq!(at(0.0, 0.0, -1.0), None);
        assert_eq!(at(3.0, 0.0, -1.0), None);
        assert!(at(0.0, 0.0, 1.0).unwrap().contains("below the floor"));
        assert!(at(0.0, 0.0, 0.1).unwrap().contains("inside a wall"));
        assert!(at(4.5, 0.5, -1.0).unwrap().contains("inside a wall"));
        assert_eq!(
            MapGeometry::default().problem_at(&Coordinates::zeros()),
            None
        );
    }

    /// Issue 20 item 4: the rescue map's victims are drawn in their colour, named.
    #[cfg(feature = "local")]
    #[test]
    fn victims_are_drawn_in_their_colour_with_their_names() {
        let map = usar_server::sim::Map::embedded("rescue").unwrap();
        let geometry = MapGeometry::from(&map);
        assert_eq!(geometry.victims.len(), 4);
        let dir = std::env::temp_dir().join(format!("ucc-victims-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path: Vec<_> = (0..40)
            .map(|i| Coordinates::new(-12.0 + f64::from(i) * 0.4, 0.0, -1.5))
            .collect();
        let picture = MapPicture {
            title: "CollapsedBuilding".into(),
            start: path.first().copied(),
            paths: vec![path],
            geometry: Some(geometry),
            ..MapPicture::default()
        };
        let files = picture.write(&dir.join("rescue")).unwrap();
        let svg = std::fs::read_to_string(&files[0]).unwrap();
        assert!(
            svg.contains("Victim3") && svg.contains("\nvictims\n</text>"),
            "names and legend"
        );
        let png = image::open(&files[1]).unwrap().to_rgb8();
        let [r, g, b] = [VICTIM_COLOUR.0, VICTIM_COLOUR.1, VICTIM_COLOUR.2];
        let victim_pixels = png.pixels().filter(|p| p.0 == [r, g, b]).count();
        assert!(victim_pixels > 400, "{victim_pixels} victim pixels");
        if std::env::var_os("UCC_KEEP_PICTURES").is_none() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn nice_lengths() {
        assert_eq!(nice_length(1.3), 1.0);
        assert_eq!(nice_length(2.5), 2.0);
        assert_eq!(nice_length(7.0), 5.0);
        assert_eq!(nice_length(0.01), 0.1);
    }

    #[test]
    fn writes_svg_and_png() {
        let dir = std::env::temp_dir().join(format!("ucc-picture-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path: Vec<_> = (0..50)
            .map(|i| {
                let t = f64::from(i) / 10.0;
                Coordinates::new(t, t.sin() * 2.0, -1.0)
            })
            .collect();
        let picture = MapPicture {
            title: "test map".into(),
            paths: vec![path.clone(), path.iter().map(|p| p * 0.5).collect()],
            repeats: Vec::new(),
            waypoints: vec![
                Coordinates::new(2.0, 1.0, -1.0),
                Coordinates::new(4.0, -1.0, -1.0),
            ],
            start: Some(Coordinates::zeros()),
            geometry: Some(MapGeometry {
                footprints: vec![Footprint {
                    outline: vec![(5.0, -3.0), (5.5, -3.0), (5.5, 3.0), (5.0, 3.0)],
                    z_min: -3.0,
                    z_max: 0.0,
                }],
                victims: Vec::new(),
            }),
            laser_hits: Vec::new(),
        };
        let files = picture.write(&dir.join("map")).unwrap();
        for f in &files {
            assert!(
                std::fs::metadata(f).unwrap().len() > 1000,
                "{f:?} is too small"
            );
        }
        let svg = std::fs::read_to_string(&files[0]).unwrap();
        assert!(svg.contains("north"));
        assert!(svg.contains("walls and obstacles"), "the map is drawn");
        // An empty picture (no data at all) still draws.
        MapPicture::default().write(&dir.join("empty")).unwrap();
        if std::env::var_os("UCC_KEEP_PICTURES").is_none() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    /// The defects: a legend entry per iteration ran off the image at 237 iterations, and
    /// the scale bar could cover the start.
    #[test]
    fn many_iterations_share_one_legend_entry_and_the_scale_bar_stays_off_the_data() {
        let dir = std::env::temp_dir().join(format!("ucc-legend-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path: Vec<_> = (0..20)
            .map(|i| Coordinates::new(f64::from(i) * 0.2, 0.0, -1.0))
            .collect();
        let picture = MapPicture {
            title: "many".into(),
            paths: vec![path; 237],
            repeats: Vec::new(),
            start: Some(Coordinates::zeros()),
            laser_hits: vec![Coordinates::new(1.0, 1.0, -1.0)],
            ..MapPicture::default()
        };
        let [svg, _] = picture.write(&dir.join("overlay")).unwrap();
        let svg = std::fs::read_to_string(svg).unwrap();
        assert!(svg.contains("paths of 237 iterations"), "one entry for all");
        assert!(!svg.contains("iteration 2<"), "no entry per iteration");
        assert!(svg.contains("laser hits"));
        assert!(
            !svg.contains("waypoint\n</text>"),
            "no waypoint in the legend of a picture without waypoints"
        );
        // The scale bar's label sits above the plot's top edge (the caption row).
        let label = svg.find(" m\n</text>").expect("a scale bar label");
        let tag = &svg[svg[..label].rfind("<text").unwrap()..label];
        let y: f64 = tag
            .split("y=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            y < f64::from(CAPTION + MARGIN + 10),
            "scale bar label at y={y}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A polyline of an SVG: its stroke colour, its width and its points.
    type Polyline = (String, f64, Vec<(f64, f64)>);

    /// The polylines of an SVG.
    fn polylines(svg: &str) -> Vec<Polyline> {
        let attr = |tag: &str, name: &str| {
            tag.split(&format!(" {name}=\""))
                .nth(1)?
                .split('"')
                .next()
                .map(str::to_owned)
        };
        svg.split("<polyline")
            .skip(1)
            .map(|tag| {
                let tag = &tag[..tag.find("/>").unwrap()];
                let points = attr(tag, "points")
                    .unwrap_or_default()
                    .split_whitespace()
                    .map(|p| {
                        let (x, y) = p.split_once(',').unwrap();
                        (x.parse().unwrap(), y.parse().unwrap())
                    })
                    .collect();
                let width = attr(tag, "stroke-width").map_or(1.0, |w| w.parse().unwrap());
                (attr(tag, "stroke").unwrap_or_default(), width, points)
            })
            .collect()
    }

    /// The defects: in a 3-iteration overlay the third path was yellow on white and hid the
    /// identical earlier ones; in a 1000-iteration overlay the legend was red and the paths
    /// brown; the waypoints were not numbered.
    #[test]
    fn overlay_paths_stay_visible_and_match_their_legend_and_waypoints_are_numbered() {
        let dir = std::env::temp_dir().join(format!("ucc-overlay-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path: Vec<_> = (0..30)
            .map(|i| Coordinates::new(f64::from(i) * 0.1, f64::from(i) * 0.05, -1.0))
            .collect();
        let waypoints = vec![
            Coordinates::new(0.0, 0.0, -1.0),
            Coordinates::new(3.0, 0.0, -1.0),
            Coordinates::new(3.0, 1.5, -1.0),
            Coordinates::new(0.0, 0.0, -1.0),
        ];
        let picture = |n: usize| MapPicture {
            title: format!("{n}"),
            paths: vec![path.clone(); n],
            repeats: Vec::new(),
            waypoints: waypoints.clone(),
            start: Some(Coordinates::zeros()),
            ..MapPicture::default()
        };
        let [svg, _] = picture(3).write(&dir.join("three")).unwrap();
        let svg = std::fs::read_to_string(svg).unwrap();
        // The three paths (the axes and ticks are black, the legend samples two points).
        let lines: Vec<_> = polylines(&svg)
            .into_iter()
            .filter(|l| l.0 != "#000000")
            .collect();
        let paths: Vec<_> = lines.iter().filter(|l| l.2.len() > 2).collect();
        assert_eq!(paths.len(), 3);
        for (colour, _, _) in &paths {
            let rgb = u32::from_str_radix(colour.trim_start_matches('#'), 16).unwrap();
            let [r, g, b] = [rgb >> 16, (rgb >> 8) & 255, rgb & 255].map(f64::from);
            let luminance = (0.299 * r + 0.587 * g + 0.114 * b) / 255.0;
            assert!(luminance < 0.7, "{colour} is too pale on white");
        }
        assert!(
            paths[0].1 > paths[1].1 && paths[1].1 > paths[2].1,
            "each later path narrower, so that identical ones all show: {:?}",
            paths.iter().map(|p| p.1).collect::<Vec<_>>()
        );
        for (label, text) in [("1, 4", "the first and the last"), ("2", "2"), ("3", "3")] {
            assert!(
                svg.contains(&format!(">\n{label}\n</text>")),
                "waypoint label {text}"
            );
        }

        let [svg, _] = picture(1000).write(&dir.join("thousand")).unwrap();
        let svg = std::fs::read_to_string(svg).unwrap();
        let lines = polylines(&svg);
        let colours: std::collections::BTreeSet<&str> = lines
            .iter()
            .map(|(c, _, _)| c.as_str())
            .filter(|c| *c != "#000000")
            .collect();
        assert_eq!(
            colours.len(),
            1,
            "paths and legend in one colour: {colours:?}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The defect: the legends of the attitude and position plots covered the data.
    #[test]
    fn plot_legends_do_not_cover_the_data() {
        let dir = std::env::temp_dir().join(format!("ucc-legends-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Roll and pitch at their largest, and positions that end high, at the right.
        let trajectory = (0..50)
            .map(|i| {
                let t = f64::from(i) * 0.1;
                TrajectoryPoint {
                    time: t,
                    position: Coordinates::new(t, t * 0.8, -1.0),
                    orientation: Some(Coordinates::new(0.1 * t / 5.0, 0.2 * t / 5.0, 0.0)),
                    velocity: None,
                    battery: None,
                }
            })
            .collect();
        let plots = Plots {
            title: "legends".into(),
            trajectory,
            waypoints: Vec::new(),
        };
        let [svg, _] = plots.write(&dir.join("plots")).unwrap();
        let svg = std::fs::read_to_string(svg).unwrap();
        // The legend boxes: white, translucent rectangles.
        let boxes: Vec<(f64, f64, f64, f64)> = svg
            .split("<rect")
            .skip(1)
            .filter(|tag| tag.contains("opacity=\"0.85\""))
            .map(|tag| {
                let num = |name: &str| -> f64 {
                    tag.split(&format!(" {name}=\""))
                        .nth(1)
                        .unwrap()
                        .split('"')
                        .next()
                        .unwrap()
                        .parse()
                        .unwrap()
                };
                (num("x"), num("y"), num("width"), num("height"))
            })
            .collect();
        assert_eq!(boxes.len(), 2, "attitude and position legends");
        for (_, _, points) in polylines(&svg).iter().filter(|l| l.2.len() > 2) {
            for &(px, py) in points {
                for &(x, y, w, h) in &boxes {
                    assert!(
                        !(x <= px && px <= x + w && y <= py && py <= y + h),
                        "data at {px},{py} under a legend at {x},{y} {w}x{h}"
                    );
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn plots_show_altitude_speed_and_battery() {
        let dir = std::env::temp_dir().join(format!("ucc-plots-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let trajectory = (0..30)
            .map(|i| TrajectoryPoint {
                time: f64::from(i) * 0.1,
                position: Coordinates::new(f64::from(i) * 0.1, 0.0, -1.0 - f64::from(i) * 0.05),
                orientation: None,
                velocity: Some(Coordinates::new(1.0, 0.0, -0.5)),
                battery: Some(1.0 - f64::from(i) * 0.001),
            })
            .collect();
        let plots = Plots {
            title: "plots".into(),
            trajectory,
            waypoints: vec![Coordinates::new(3.0, 0.0, -2.5)],
        };
        let [svg, png] = plots.write(&dir.join("plots")).unwrap();
        let svg = std::fs::read_to_string(svg).unwrap();
        for caption in [
            "side view",
            "altitude",
            "speed",
            "battery",
            "attitude",
            "pitch",
            "horizontal position",
        ] {
            assert!(svg.contains(caption), "{caption}");
        }
        assert!(std::fs::metadata(png).unwrap().len() > 1000);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
