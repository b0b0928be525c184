//! The map picture of the original map window: the paths seen from above (x north up,
//! y east right), the waypoints as red squares, the start, axes in metres and a scale bar;
//! written as SVG and PNG.
//!
//! PNG text is drawn with the DejaVu Sans font embedded in the crate
//! (`assets/DejaVuSans.ttf`, Bitstream Vera license in `assets/DejaVuSans-LICENSE.txt`), so no
//! system font is needed.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::geometry::Coordinates;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Side of the square plotting area, pixels.
const PLOT_SIDE: u32 = 700;
const MARGIN: u32 = 20;
const X_LABELS: u32 = 50;
const Y_LABELS: u32 = 60;
const CAPTION: u32 = 40;

/// What to draw.
#[derive(Debug, Clone, Default)]
pub struct MapPicture {
    /// The caption.
    pub title: String,
    /// One path per iteration (world frame, z ignored).
    pub paths: Vec<Vec<Coordinates>>,
    /// The waypoints.
    pub waypoints: Vec<Coordinates>,
    /// The start position.
    pub start: Option<Coordinates>,
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

impl MapPicture {
    /// Writes `<base>.svg` and `<base>.png`; returns their paths.
    pub fn write(&self, base: &Path) -> Result<[PathBuf; 2], PictureError> {
        let svg = base.with_extension("svg");
        let png = base.with_extension("png");
        let size = (
            PLOT_SIDE + Y_LABELS + 2 * MARGIN,
            PLOT_SIDE + X_LABELS + CAPTION + 2 * MARGIN,
        );
        let failed = |path: &Path| {
            let path = path.to_owned();
            move |message: String| PictureError { path, message }
        };
        // Both backends measure text with the font.
        register_font().map_err(failed(&svg))?;
        self.draw(SVGBackend::new(&svg, size).into_drawing_area())
            .map_err(failed(&svg))?;
        self.draw(BitMapBackend::new(&png, size).into_drawing_area())
            .map_err(failed(&png))?;
        Ok([svg, png])
    }

    /// The square region shown, in chart coordinates (east, north): it holds every point with
    /// a margin, and is at least 4 m wide.
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
        let half = ((hi.0 - lo.0).max(hi.1 - lo.1) * 1.15 / 2.0).max(2.0);
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
        for (i, path) in self.paths.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let label = if self.paths.len() > 1 {
                format!("iteration {}", i + 1)
            } else {
                "path".to_owned()
            };
            chart
                .draw_series(LineSeries::new(
                    path.iter().map(top_view),
                    color.stroke_width(2),
                ))
                .map_err(err)?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .draw_series(self.waypoints.iter().map(|p| {
                EmptyElement::at(top_view(p)) + Rectangle::new([(-5, -5), (5, 5)], RED.filled())
            }))
            .map_err(err)?
            .label("waypoint")
            .legend(|(x, y)| Rectangle::new([(x + 5, y - 5), (x + 15, y + 5)], RED.filled()));
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
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(err)?;

        // Scale bar: a round length about a fifth of the width, bottom left.
        let width = east.end - east.start;
        let length = nice_length(width / 5.0);
        let (x0, y0) = (east.start + width * 0.05, north.start + width * 0.05);
        chart
            .draw_series([PathElement::new(
                [(x0, y0), (x0 + length, y0)],
                BLACK.stroke_width(3),
            )])
            .map_err(err)?;
        chart
            .draw_series([Text::new(
                format!("{length} m"),
                (x0, y0 + width * 0.035),
                ("sans-serif", 14).into_font().color(&BLACK),
            )])
            .map_err(err)?;
        root.present().map_err(err)
    }
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
            waypoints: vec![
                Coordinates::new(2.0, 1.0, -1.0),
                Coordinates::new(4.0, -1.0, -1.0),
            ],
            start: Some(Coordinates::zeros()),
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
        // An empty picture (no data at all) still draws.
        MapPicture::default().write(&dir.join("empty")).unwrap();
        if std::env::var_os("UCC_KEEP_PICTURES").is_none() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }
}
