//! Line plots as SVG text: axes with ticks, polylines, a legend.
//!
//! Small on purpose: the pictures whirl draws are a few polylines over labelled axes, which a
//! browser or an image viewer shows as they are; no fonts, no rasteriser.

use std::fmt::Write as _;

/// One polyline of a plot.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// CSS colour.
    pub colour: &'static str,
    /// Points in data coordinates.
    pub points: Vec<(f64, f64)>,
}

/// A plot: title, axis labels, series; `equal_scale` keeps one data unit the same length on
/// both axes (for sections, where shape matters).
#[derive(Debug, Clone)]
pub struct Plot {
    /// Title above the plot.
    pub title: String,
    /// Horizontal axis label.
    pub x_label: String,
    /// Vertical axis label.
    pub y_label: String,
    /// The polylines.
    pub series: Vec<Series>,
    /// Same scale on both axes.
    pub equal_scale: bool,
}

/// A plot's size, px.
pub(crate) const WIDTH: f64 = 900.0;
/// A plot's height, px.
pub(crate) const HEIGHT: f64 = 600.0;
const MARGIN: f64 = 70.0;

impl Plot {
    /// The plot as an SVG document.
    pub fn to_svg(&self) -> String {
        let pts = self.series.iter().flat_map(|s| s.points.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in pts.filter(|(x, y)| x.is_finite() && y.is_finite()) {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !x0.is_finite() {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        if x1 - x0 < 1e-12 {
            (x0, x1) = (x0 - 0.5, x1 + 0.5);
        }
        if y1 - y0 < 1e-12 {
            (y0, y1) = (y0 - 0.5, y1 + 0.5);
        }
        let (w, h) = (WIDTH - 2.0 * MARGIN, HEIGHT - 2.0 * MARGIN);
        let (mut sx, mut sy) = (w / (x1 - x0), h / (y1 - y0));
        if self.equal_scale {
            let s = sx.min(sy);
            (sx, sy) = (s, s);
        }
        let px = |x: f64| MARGIN + (x - x0) * sx;
        let py = |y: f64| HEIGHT - MARGIN - (y - y0) * sy;
        let mut out = String::new();
        let _ = writeln!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="13">"#
        );
        let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            out,
            r#"<text x="{}" y="30" text-anchor="middle" font-size="16">{}</text>"#,
            WIDTH / 2.0,
            escape(&self.title)
        );
        let (ax0, ax1, ay0, ay1) = (px(x0), px(x1), py(y0), py(y1));
        let _ = writeln!(
            out,
            r#"<path d="M{ax0:.1} {ay1:.1} V{ay0:.1} H{ax1:.1}" fill="none" stroke="black"/>"#
        );
        for t in ticks(x0, x1) {
            let x = px(t);
            let _ = writeln!(
                out,
                r#"<line x1="{x:.1}" y1="{ay0:.1}" x2="{x:.1}" y2="{:.1}" stroke="black"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
                ay0 + 5.0,
                ay0 + 20.0,
                label(t)
            );
        }
        for t in ticks(y0, y1) {
            let y = py(t);
            let _ = writeln!(
                out,
                r#"<line x1="{:.1}" y1="{y:.1}" x2="{ax0:.1}" y2="{y:.1}" stroke="black"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"#,
                ax0 - 5.0,
                ax0 - 8.0,
                y + 4.0,
                label(t)
            );
        }
        let _ = writeln!(
            out,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
            (ax0 + ax1) / 2.0,
            HEIGHT - 20.0,
            escape(&self.x_label)
        );
        let _ = writeln!(
            out,
            r#"<text x="20" y="{:.1}" text-anchor="middle" transform="rotate(-90 20 {:.1})">{}</text>"#,
            (ay0 + ay1) / 2.0,
            (ay0 + ay1) / 2.0,
            escape(&self.y_label)
        );
        let mut entries = 0;
        for s in &self.series {
            // A point that is not finite is a gap: the line stops there and starts again.
            let mut d = String::new();
            let mut pen_down = false;
            for &(x, y) in &s.points {
                if !(x.is_finite() && y.is_finite()) {
                    pen_down = false;
                    continue;
                }
                let _ = write!(
                    d,
                    "{}{:.2} {:.2} ",
                    if pen_down { 'L' } else { 'M' },
                    px(x),
                    py(y)
                );
                pen_down = true;
            }
            if !d.is_empty() {
                let _ = writeln!(
                    out,
                    r#"<path d="{}" fill="none" stroke="{}" stroke-width="1.5"/>"#,
                    d.trim_end(),
                    s.colour
                );
            }
            // A series without a label (the other side of a band) has no legend entry.
            if s.label.is_empty() {
                continue;
            }
            let ly = MARGIN + 18.0 * f64::from(entries);
            entries += 1;
            let _ = writeln!(
                out,
                r#"<line x1="{:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{}" stroke-width="2"/><text x="{:.1}" y="{:.1}">{}</text>"#,
                WIDTH - MARGIN - 220.0,
                WIDTH - MARGIN - 195.0,
                s.colour,
                WIDTH - MARGIN - 188.0,
                ly + 4.0,
                escape(&s.label)
            );
        }
        out.push_str("</svg>\n");
        out
    }
}

/// Several plots stacked top to bottom in one SVG document (each keeps its own axes).
pub fn stack(plots: &[Plot]) -> String {
    let mut out = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{}" viewBox="0 0 {WIDTH} {}">"#,
        HEIGHT * plots.len() as f64,
        HEIGHT * plots.len() as f64
    );
    out.push('\n');
    for (i, plot) in plots.iter().enumerate() {
        let inner = plot.to_svg();
        // Nest each plot's document, moved down to its slot.
        let moved = inner.replacen("<svg ", &format!(r#"<svg y="{}" "#, HEIGHT * i as f64), 1);
        out.push_str(&moved);
    }
    out.push_str("</svg>\n");
    out
}

/// About six round tick values covering [a, b].
fn ticks(a: f64, b: f64) -> Vec<f64> {
    let raw = (b - a) / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (a / step).ceil() as i64;
    let last = (b / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

fn label(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// `s` as SVG text.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stacked_plots_nest_one_document_each_in_its_slot() {
        let one = Plot {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![],
            equal_scale: false,
        };
        let svg = stack(&[one.clone(), one]);
        assert_eq!(svg.matches("<svg ").count(), 3);
        assert!(svg.contains(&format!(r#"<svg y="{HEIGHT}""#)));
        assert_eq!(svg.matches("</svg>").count(), 3);
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(ticks(0.0, 10.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t = ticks(-0.013, 0.021);
        assert!(t.len() >= 4 && t.iter().all(|v| (-0.013..=0.021).contains(v)));
    }

    #[test]
    fn a_plot_is_one_svg_document_with_a_path_per_series() {
        let plot = Plot {
            title: "a < b & c".into(),
            x_label: "z, mm".into(),
            y_label: "ρ, mm".into(),
            series: vec![
                Series {
                    label: "one".into(),
                    colour: "black",
                    points: vec![(0.0, 0.0), (1.0, 2.0)],
                },
                Series {
                    label: "two".into(),
                    colour: "red",
                    points: vec![(0.5, 1.0)],
                },
            ],
            equal_scale: true,
        };
        let svg = plot.to_svg();
        assert!(svg.starts_with("<svg ") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(
            svg.matches("<path d=\"M").count(),
            1 + 2,
            "axes and two series"
        );
        assert!(svg.contains("a &lt; b &amp; c"), "text is escaped");
    }

    #[test]
    fn a_gap_breaks_the_line_and_an_unlabelled_series_has_no_legend_entry() {
        let plot = Plot {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            series: vec![
                Series {
                    label: "cut".into(),
                    colour: "black",
                    points: vec![(0.0, 0.0), (1.0, 1.0), (f64::NAN, f64::NAN), (2.0, 0.0)],
                },
                Series {
                    label: String::new(),
                    colour: "green",
                    points: vec![(0.0, 1.0), (2.0, 1.0)],
                },
            ],
            equal_scale: false,
        };
        let svg = plot.to_svg();
        let cut = svg
            .lines()
            .find(|l| l.contains("stroke=\"black\" stroke-width=\"1.5\""))
            .unwrap();
        assert_eq!(cut.matches('M').count(), 2, "{cut}");
        assert_eq!(cut.matches('L').count(), 1, "{cut}");
        // One legend entry: a line of width 2 and its text.
        assert_eq!(svg.matches("stroke-width=\"2\"").count(), 1, "{svg}");
    }
}
