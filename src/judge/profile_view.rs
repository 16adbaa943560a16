//! What whirl understood of a job's groove, before anything is cut: `whirl profile` prints it
//! and writes its axial section, the console's job page shows it.
//!
//! For a standard form, the form's dimensions as its standard names them and the standard
//! they come from; for points, what the curve through them is: its radius range (the depth),
//! its tightest concave stretch, how far a fit lies from the points, how many there are. For
//! every groove its lead, starts, hand and axial pitch, and a plot of the axial section.

use crate::config::job::{Hand, Job, SectionSpec};
use crate::geometry::profile::axial_section::AxialSection;
use crate::geometry::profile::standard::StandardError;
use crate::geometry::profile::Material;
use crate::judge::svg::{self, Plot, Series};
use std::fmt::Write as _;

/// Points of the axial section `whirl profile -o` writes and the plot draws, spaced evenly
/// along the profile (more next to its corners).
pub const SECTION_POINTS: usize = 2000;

/// Decimals of the axial section's CSV: 0.1 nm, far below any machine's resolution, so the
/// groove read back is the one sampled.
pub const CSV_DECIMALS: usize = 10;

/// A concave stretch is one curved tighter than this, mm: any curvature a nose could feel.
const CONCAVE_RADIUS: f64 = 1e6;

/// One line of what whirl understood: "thread height h3", "4.0000 mm".
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Fact {
    /// What it is.
    pub name: String,
    /// Its value, with its unit.
    pub value: String,
}

/// A job's groove as `whirl profile` and the console show it.
#[derive(Debug, Clone)]
pub struct ProfileView {
    /// What whirl understood, in order.
    pub facts: Vec<Fact>,
    /// The axial section at polar angle 0 over one pitch.
    pub section: AxialSection,
}

fn fact(name: impl Into<String>, value: impl Into<String>) -> Fact {
    Fact {
        name: name.into(),
        value: value.into(),
    }
}

/// The view of `job`'s groove. Fails only where the job's standard form refuses its pitch,
/// which loading the job has checked already.
pub fn view(job: &Job) -> Result<ProfileView, StandardError> {
    let groove = &job.groove;
    let spec = &groove.profile;
    let pitch = groove.lead / f64::from(groove.starts);
    let p = job.p();
    let section = job.profile.axial_section(p, SECTION_POINTS);
    let mut facts = Vec::new();
    match (&job.form, spec.standard, spec.designation.as_deref()) {
        (Some(form), kind, designation) => {
            // A form comes from a designation, or else from a standard and its dimensions.
            let named = designation
                .map(|text| format!("designation = \"{text}\""))
                .or(kind.map(|kind| format!("standard = \"{}\"", kind.name())))
                .unwrap_or_default();
            facts.push(fact("profile", named));
            facts.push(fact("source", form.source()));
            let dimensions = match groove.material() {
                Material::Inside => form.dimensions(pitch)?,
                Material::Outside => form.internal_dimensions(pitch)?,
            };
            for d in dimensions {
                let value = if d.unit == "°" {
                    format!("{:.2}°", d.value)
                } else {
                    format!("{:.4} {}", d.value, d.unit)
                };
                facts.push(fact(d.name, value));
            }
        }
        _ => {
            let section = match spec.section.unwrap_or(SectionSpec::Transverse) {
                SectionSpec::Transverse => "transverse (x, y)",
                SectionSpec::Axial => "axial (rho, z)",
            };
            let file = spec
                .points
                .as_ref()
                .map_or(String::new(), |f| f.display().to_string());
            let mirrored = if spec.mirror == Some(true) {
                ", half a period mirrored"
            } else {
                ""
            };
            facts.push(fact(
                "profile",
                format!("points from {file}, {section} section{mirrored}"),
            ));
            if let Some(n) = job.profile.spline_points() {
                facts.push(fact("points per period", n.to_string()));
            }
            facts.push(fact(
                "fit",
                match job.profile.fit() {
                    Some(fit) => format!(
                        "within {:.6} mm of the points (largest at line {}; band {:.3e} mm)",
                        fit.deviation, fit.line, fit.band
                    ),
                    None => "none: the spline passes through every point".into(),
                },
            ));
        }
    }
    let (rho_min, rho_max) = job.profile.radius_range();
    facts.push(fact(
        "radius range",
        format!(
            "ρ {rho_min:.4} to {rho_max:.4} mm: depth {:.4} mm",
            rho_max - rho_min
        ),
    ));
    facts.push(fact("smallest concave radius", concave(job, &section)));
    facts.push(fact("lead", format!("{} mm", groove.lead)));
    facts.push(fact("starts", groove.starts.to_string()));
    facts.push(fact(
        "hand",
        match groove.hand {
            Hand::Right => "right",
            Hand::Left => "left",
        },
    ));
    facts.push(fact("axial pitch", format!("{pitch} mm")));
    Ok(ProfileView { facts, section })
}

/// The tightest concave stretch across the groove and where it is, in the axial section's
/// `(ρ, z)` within the window of `section`.
fn concave(job: &Job, section: &AxialSection) -> String {
    let p = job.p();
    let tightest = job
        .profile
        .concave_stretches(p, CONCAVE_RADIUS)
        .into_iter()
        .min_by(|a, b| a.min_radius.total_cmp(&b.min_radius));
    match tightest {
        None => "none: the groove is nowhere concave".into(),
        Some(s) => {
            let z0 = section.points.first().map_or(0.0, |q| q.y);
            let z = z0 + (-p * s.at.to_angle() - z0).rem_euclid(section.pitch());
            let rho = s.at.length();
            let radius = if s.min_radius == 0.0 {
                "0 (a sharp corner)".to_string()
            } else {
                format!("{:.4} mm", s.min_radius)
            };
            format!("{radius} across the groove, at ρ {rho:.4} mm, z {z:.4} mm")
        }
    }
}

impl ProfileView {
    /// The axial section as an axial points file: `rho,z`, mm, [`CSV_DECIMALS`] decimals.
    pub fn csv(&self) -> String {
        let mut out = String::from("rho,z\n");
        for q in &self.section.points {
            let _ = writeln!(out, "{:.*},{:.*}", CSV_DECIMALS, q.x, CSV_DECIMALS, q.y);
        }
        out
    }

    /// The axial section drawn to scale: the groove, its crest line, its depth where it is
    /// deepest, and below the plot every fact with the form's dimensions.
    pub fn svg(&self, title: &str) -> String {
        let pts = &self.section.points;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for q in pts {
            (lo, hi) = (lo.min(q.x), hi.max(q.x));
        }
        let (z0, z1) = match (pts.first(), pts.last()) {
            (Some(a), Some(b)) => (a.y, b.y),
            _ => (0.0, 0.0),
        };
        // The middle of the deepest stretch (a flat root is deepest all along).
        let deepest: Vec<f64> = pts
            .iter()
            .filter(|q| q.x - lo < 1e-9)
            .map(|q| q.y)
            .collect();
        let z_deep = deepest.iter().sum::<f64>() / deepest.len().max(1) as f64;
        let plot = Plot {
            title: title.into(),
            x_label: "z, mm (axial, at polar angle 0)".into(),
            y_label: "ρ, mm (radius)".into(),
            series: vec![
                Series {
                    label: format!("crest ρ = {hi:.4} mm"),
                    colour: "silver",
                    points: vec![(z0, hi), (z1, hi)],
                },
                Series {
                    label: format!("depth {:.4} mm", hi - lo),
                    colour: "firebrick",
                    points: vec![(z_deep, lo), (z_deep, hi)],
                },
                Series {
                    label: "groove".into(),
                    colour: "black",
                    points: pts.iter().map(|q| (q.y, q.x)).collect(),
                },
                // A lone point, drawn as nothing: room above the crest for the legend.
                Series {
                    label: String::new(),
                    colour: "none",
                    points: vec![(z0, hi + 0.2 * (hi - lo))],
                },
            ],
            equal_scale: true,
        };
        let lines = &self.facts;
        let line_height = 18.0;
        let height = svg::HEIGHT + 10.0 + line_height * lines.len() as f64;
        let mut out = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" class="profile" width="{w}" height="{height}" viewBox="0 0 {w} {height}" font-family="sans-serif" font-size="13">"#,
            w = svg::WIDTH
        );
        out.push('\n');
        let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
        out.push_str(&plot.to_svg());
        for (i, f) in lines.iter().enumerate() {
            let y = svg::HEIGHT + line_height * (i as f64 + 0.5);
            let _ = writeln!(
                out,
                r#"<text class="dimension" x="70" y="{y:.1}">{}: {}</text>"#,
                svg::escape(&f.name),
                svg::escape(&f.value)
            );
        }
        out.push_str("</svg>\n");
        out
    }
}
