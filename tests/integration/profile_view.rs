//! `whirl profile` through the real binary: what it says of a standard form and of points,
//! the axial section it writes (checked against ISO 2904's Tr 40x7, and read back as the same
//! groove for a standard form, points and multi-start grooves), the plot it draws (well-formed
//! SVG with the groove and the form's dimensions), and its refusals, which write nothing.

use crate::util;
use glam::DVec2;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use whirl::config::job::Job;
use whirl::geometry::profile::Profile;

fn os(s: &str) -> &OsStr {
    OsStr::new(s)
}

/// Tr 40x7: ISO 2904's basic profile (sharp root corners), one start, right hand.
const TR_40X7: &str = r#"
[groove]
lead = 7.0
starts = 1
hand = "right"
z_start = 0.0
length = 40.0

[groove.profile]
standard = "trapezoidal"
major_diameter = 40.0

[tool]
whirling = "internal"
ring_radius = 32.0
nose_radius = 0.4
inserts = 4

[cut]
delta = 0.01
axial_feed = 0.05
workpiece_rpm = 12.0
ring_rpm = 3000.0
"#;

/// `whirl profile JOB ARGS…`, which must succeed; its standard output.
fn profile(job: &Path, args: &[&OsStr]) -> String {
    let mut all = vec![os("profile"), job.as_os_str()];
    all.extend_from_slice(args);
    let o = util::whirl(&all);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{all:?}: {stderr}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `whirl profile ARGS…`, which must be refused (exit 1, no panic); its standard error.
fn refused(args: &[&OsStr]) -> String {
    let mut all = vec![os("profile")];
    all.extend_from_slice(args);
    let o = util::whirl(&all);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{all:?} must be refused: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

/// The rows of an axial section CSV, after checking its header and that every value is
/// written to ten decimals.
fn read_section(path: &Path) -> Vec<DVec2> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("rho,z"), "the header");
    lines
        .map(|line| {
            let (rho, z) = line.split_once(',').unwrap();
            for v in [rho, z] {
                let decimals = v.split_once('.').map_or(0, |(_, d)| d.len());
                assert_eq!(decimals, 10, "{line}: ten decimals");
            }
            DVec2::new(rho.parse().unwrap(), z.parse().unwrap())
        })
        .collect()
}

/// `job` with its profile replaced by the axial points in `csv`.
fn axial_job(job: &Path, csv: &Path, dir: &Path) -> PathBuf {
    let mut table: toml::Table = std::fs::read_to_string(job).unwrap().parse().unwrap();
    let mut spec = toml::Table::new();
    spec.insert("section".into(), "axial".into());
    spec.insert("points".into(), csv.display().to_string().into());
    table["groove"]
        .as_table_mut()
        .unwrap()
        .insert("profile".into(), spec.into());
    util::write(dir, "axial.toml", &toml::to_string(&table).unwrap())
}

/// The transverse point of `profile` at polar angle `phi` (its polar angle increases along
/// its parameter, so bisection finds it), with its unit normal.
fn at_angle(profile: &Profile, phi: f64) -> (DVec2, DVec2) {
    let angle = |u: f64| profile.point(u).pos.to_angle();
    let start = angle(0.0);
    // The angle gained from the start, in [0, period).
    let gained = |a: f64| (a - start).rem_euclid(std::f64::consts::TAU);
    let target = gained(phi).min(profile.period());
    let (mut lo, mut hi) = (0.0, profile.length());
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if gained(angle(mid)) < target && gained(angle(mid)) < profile.period() - 1e-12 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let q = profile.point(lo);
    (q.pos, q.tangent.perp())
}

/// The largest distance between two transverse profiles of one groove, to first order: at
/// each of `n` polar angles spread over the period, the radial gap between them projected
/// on the first one's normal (both are curves of increasing polar angle, so the point of
/// each at one angle is the other's nearest but for the slope of the curve).
fn distance(a: &Profile, b: &Profile, n: usize) -> f64 {
    let start = a.point(0.0).pos.to_angle();
    (0..n)
        .map(|k| {
            let phi = start + a.period() * (k as f64 + 0.5) / n as f64;
            let (pa, normal) = at_angle(a, phi);
            let (pb, _) = at_angle(b, phi);
            let radial = pa.normalize();
            ((pb.length() - pa.length()) * normal.dot(radial)).abs()
        })
        .fold(0.0, f64::max)
}

/// The bound the groove read back from the section keeps to, from the section itself, in
/// the transverse plane where whirl fits its spline (point `k` at radius ρ and polar angle
/// −z/p):
/// - the spline through a corner turning by θ, with spans h beside it, leaves the corner's
///   two sides by less than h·θ/2 (its tangent over those spans turns within the corner's,
///   so over a span of h it departs from the chord by at most h·sin(θ)/2); the sampler's
///   spans beside a corner are an eighth of its largest ones, `H`, and the largest turn
///   between two chords is θ: h·θ/2 = H·θ/16. Away from corners the spline's error is
///   of the order h⁴, far below;
/// - ten decimals move a value by 5·10⁻¹¹ mm, a transverse point by that times (1 + ρ/|p|):
///   a nanometre here, bounded by 10⁻⁸ mm with room for the spline's amplification of it.
fn bound(section: &[DVec2], p: f64) -> f64 {
    let transverse: Vec<DVec2> = section
        .iter()
        .map(|q| q.x * DVec2::from_angle(-q.y / p))
        .collect();
    let chords: Vec<DVec2> = transverse.windows(2).map(|w| w[1] - w[0]).collect();
    let longest = chords.iter().map(|c| c.length()).fold(0.0, f64::max);
    let turn = chords
        .windows(2)
        .map(|w| w[0].angle_to(w[1]).abs())
        .fold(0.0, f64::max);
    longest * turn / 16.0 + 1e-8
}

/// `whirl profile JOB -o CSV`, then the job with `section = "axial"` and that CSV loaded:
/// the same groove within [`bound`]; and the section spans one axial pitch.
fn reads_back_as_the_same_groove(job: &Path) {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("section.csv");
    profile(job, &[os("-o"), csv.as_os_str()]);
    let section = read_section(&csv);
    let original = Job::load(job).unwrap();
    let pitch = original.groove.lead / f64::from(original.groove.starts);
    assert!(section.len() >= 1000, "{} points", section.len());
    let span = section[section.len() - 1].y - section[0].y;
    assert!(
        (span - pitch).abs() < 1e-9,
        "z spans {span}, the pitch is {pitch}"
    );
    let again = Job::load(&axial_job(job, &csv, dir.path())).unwrap();
    assert_eq!(again.groove.starts, original.groove.starts);
    let (gap, allowed) = (
        distance(&original.profile, &again.profile, 20_000),
        bound(&section, original.p()),
    );
    eprintln!(
        "{}: {gap:.3e} mm apart, bound {allowed:.3e} mm",
        job.display()
    );
    assert!(
        gap <= allowed,
        "{}: {gap} mm apart, beyond {allowed} mm",
        job.display()
    );
    // Both ways round: the second profile's points lie as close to the first.
    let back = distance(&again.profile, &original.profile, 20_000);
    assert!(
        back <= allowed,
        "{}: {back} mm back, beyond {allowed} mm",
        job.display()
    );
}

#[test]
fn the_tr_40x7_section_is_iso_2904_s_profile_over_one_pitch() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::write(dir.path(), "tr40x7.toml", TR_40X7);
    let csv = dir.path().join("section.csv");
    let said = profile(&job, &[os("-o"), csv.as_os_str()]);
    let pts = read_section(&csv);
    assert!(pts.len() >= 1000, "{} points", pts.len());
    assert!(pts.windows(2).all(|w| w[1].y > w[0].y), "z increases");
    // ISO 2904, P = 7: the section spans the pitch, the crest is at d/2 = 20, the root at
    // d3/2 = (d − 2·h3)/2 with h3 = 0.5·P + a_c = 3.5 + 0.5 = 4 mm.
    let span = pts[pts.len() - 1].y - pts[0].y;
    assert!((span - 7.0).abs() < 1e-9, "z spans {span}");
    let (lo, hi) = pts.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), q| {
        (lo.min(q.x), hi.max(q.x))
    });
    assert!((hi - 20.0).abs() < 1e-9, "crest at ρ {hi}");
    assert!((hi - lo - 4.0).abs() < 1e-9, "depth {}", hi - lo);
    // ISO 2901's 30° thread angle: each flank leans 15° from the radial direction.
    let flank: Vec<DVec2> = pts
        .iter()
        .copied()
        .filter(|q| q.x > 16.5 && q.x < 19.5)
        .collect();
    assert!(flank.len() > 50, "points on the flanks");
    let leans: Vec<f64> = flank
        .windows(2)
        .filter(|w| (w[1].y - w[0].y).abs() < 0.1)
        .map(|w| ((w[1].y - w[0].y) / (w[1].x - w[0].x)).atan().to_degrees())
        .collect();
    assert!(
        leans.iter().any(|&a| a > 0.0) && leans.iter().any(|&a| a < 0.0),
        "both flanks"
    );
    for lean in leans {
        assert!((lean.abs() - 15.0).abs() < 1e-6, "a flank at {lean}°");
    }
    // What it says: the standard, its source and h3, and the groove's figures.
    for words in [
        "standard = \"trapezoidal\"",
        "ISO 2904",
        "thread height h3",
        "4.0000 mm",
        "depth 4.0000 mm",
        "axial pitch",
        "hand",
    ] {
        assert!(said.contains(words), "says {words:?}: {said}");
    }
    // The root corners are sharp: the tightest concave stretch is a corner, on the root.
    let concave = said
        .lines()
        .find(|l| l.contains("smallest concave radius"))
        .unwrap();
    assert!(
        concave.contains("sharp corner") && concave.contains("ρ 16.0000"),
        "{concave}"
    );
    // Such a corner does not read back (docs/profiles.md): the points reader refuses it as
    // an outlier, naming a root corner's line.
    let error = Job::load(&axial_job(&job, &csv, dir.path()))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("section.csv") && error.contains("(16, "),
        "{error}"
    );
}

#[test]
fn a_standard_form_reads_back_as_the_same_groove() {
    let dir = tempfile::tempdir().unwrap();
    // Tr 40x7 with ISO 2904's largest root fillet, R1 = 0.5·a_c = 0.25 mm. (A sharp root
    // corner is concave: the points reader takes a sharp concave corner for a zig-zag and
    // refuses it as an outlier, and no nose of finite radius could cut it anyway.)
    let filleted = TR_40X7.replace(
        "major_diameter = 40.0",
        "major_diameter = 40.0\nroot_radius = 0.25",
    );
    reads_back_as_the_same_groove(&util::write(dir.path(), "tr40x7.toml", &filleted));
    // Tr 40x14 P7, two starts, with root fillets.
    reads_back_as_the_same_groove(&util::example("trapezoidal"));
    reads_back_as_the_same_groove(&util::example("ball-screw"));
}

#[test]
fn points_read_back_as_the_same_groove() {
    // Left hand, a whole period of transverse points.
    reads_back_as_the_same_groove(&util::example("left-external"));
    // Two starts, half a period mirrored.
    reads_back_as_the_same_groove(&util::example("double-start"));
}

#[test]
fn a_points_profile_is_described_by_what_the_curve_is() {
    let said = profile(&util::example("double-start"), &[]);
    // The example's points: 13 rows from the root (26, 0) to the crest (0, 34), a half
    // period mirrored into 24 distinct points.
    for words in [
        "points from profile.csv, transverse (x, y) section, half a period mirrored",
        "points per period",
        "24",
        "ρ 26.0000 to 34.0000 mm: depth 8.0000 mm",
        "none: the spline passes through every point",
        "starts",
    ] {
        assert!(said.contains(words), "says {words:?}: {said}");
    }
}

/// A check that `text` is well-formed XML: every tag closed in order, attributes quoted,
/// no stray `<` or `&`; the names of its elements.
fn well_formed(text: &str) -> Vec<String> {
    let mut open: Vec<String> = Vec::new();
    let mut names = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find(['<', '&']) {
        let (before, tail) = rest.split_at(at);
        assert!(!before.contains('>'), "a stray > before {tail:.40}");
        if tail.starts_with('&') {
            let end = tail.find(';').expect("an entity ends with ;");
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].contains(&&tail[..=end]),
                "entity {}",
                &tail[..=end]
            );
            rest = &tail[end + 1..];
            continue;
        }
        let end = tail.find('>').expect("a tag ends with >");
        let tag = &tail[1..end];
        rest = &tail[end + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(
                open.pop().as_deref(),
                Some(name.trim()),
                "closing </{name}>"
            );
            continue;
        }
        let closed = tag.ends_with('/');
        let tag = tag.trim_end_matches('/');
        let name = tag.split_whitespace().next().expect("a tag has a name");
        assert!(
            name.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == ':'),
            "tag name {name:?}"
        );
        assert_eq!(
            tag.matches('"').count() % 2,
            0,
            "attributes quoted: <{tag}>"
        );
        assert!(!tag.contains('<'), "<{tag}>");
        names.push(name.to_owned());
        if !closed {
            open.push(name.to_owned());
        }
    }
    assert!(open.is_empty(), "unclosed {open:?}");
    names
}

#[test]
fn the_plot_is_well_formed_svg_with_the_groove_and_the_form_s_dimensions() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("plot.svg");
    profile(
        &util::example("trapezoidal"),
        &[os("--svg"), svg.as_os_str()],
    );
    let text = std::fs::read_to_string(&svg).unwrap();
    let names = well_formed(&text);
    assert_eq!(names.first().map(String::as_str), Some("svg"));
    assert!(
        names.iter().filter(|n| *n == "path").count() >= 4,
        "axes, crest, depth, groove"
    );
    for words in [
        "z, mm",
        "ρ, mm",
        "groove",
        "crest ρ = 20.0000 mm",
        "depth",
        "thread height h3",
        "flank angle: 30.00°",
        "root radius: 0.5000 mm",
    ] {
        assert!(text.contains(words), "the plot shows {words:?}");
    }
    // The groove's path: one pitch's worth of points, drawn as one line.
    let groove = text
        .lines()
        .rfind(|l| {
            l.starts_with("<path d=\"M") && l.contains("stroke=\"black\" stroke-width=\"1.5\"")
        })
        .expect("the groove's path");
    assert!(
        groove.matches('L').count() >= 1000,
        "{} points",
        groove.matches('L').count()
    );
    assert!(well_formed("<a><b/>&amp;</a>") == ["a", "b"]);
}

#[test]
fn a_job_that_does_not_load_writes_nothing_and_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, svg) = (dir.path().join("s.csv"), dir.path().join("s.svg"));
    let args = |job: &Path| {
        [
            job.as_os_str().to_owned(),
            "-o".into(),
            csv.as_os_str().to_owned(),
            "--svg".into(),
            svg.as_os_str().to_owned(),
        ]
    };
    let missing = dir.path().join("missing.toml");
    let a = args(&missing);
    let said = refused(&a.iter().map(|s| s.as_os_str()).collect::<Vec<_>>());
    assert!(said.contains("missing.toml"), "{said}");
    let bad = util::write(
        dir.path(),
        "bad.toml",
        &TR_40X7.replace("lead = 7.0", "lead = -7.0"),
    );
    let a = args(&bad);
    let said = refused(&a.iter().map(|s| s.as_os_str()).collect::<Vec<_>>());
    assert!(said.contains("groove.lead"), "{said}");
    assert!(!csv.exists() && !svg.exists(), "nothing written");
    // A file that was there before a failed run is left as it was.
    std::fs::write(&csv, "kept").unwrap();
    refused(&a.iter().map(|s| s.as_os_str()).collect::<Vec<_>>());
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "kept");
}

#[test]
fn outputs_that_cannot_be_written_are_refused_before_the_job_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::write(dir.path(), "tr40x7.toml", TR_40X7);
    let svg = dir.path().join("plot.svg");
    let nowhere = dir.path().join("no-such-folder").join("s.csv");
    let said = refused(&[
        job.as_os_str(),
        os("-o"),
        nowhere.as_os_str(),
        os("--svg"),
        svg.as_os_str(),
    ]);
    assert!(
        said.contains("refusing to write") && said.contains("(-o)"),
        "{said}"
    );
    assert!(!svg.exists(), "the plot is not written either");
    // The job itself, and one file named twice.
    let said = refused(&[job.as_os_str(), os("-o"), job.as_os_str()]);
    assert!(said.contains("the job file"), "{said}");
    assert_eq!(
        std::fs::read_to_string(&job).unwrap(),
        TR_40X7,
        "the job untouched"
    );
    let said = refused(&[
        job.as_os_str(),
        os("-o"),
        svg.as_os_str(),
        os("--svg"),
        svg.as_os_str(),
    ]);
    assert!(said.contains("names the same file"), "{said}");
    // A points profile's own points.
    let example = util::example("double-start");
    let points = example.with_file_name("profile.csv");
    let before = std::fs::read(&points).unwrap();
    let said = refused(&[example.as_os_str(), os("-o"), points.as_os_str()]);
    assert!(said.contains("profile points"), "{said}");
    assert_eq!(std::fs::read(&points).unwrap(), before);
}
