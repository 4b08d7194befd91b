//! `roadtrack analyze`: counts, turning movements, speeds, headways and lane use.

use crate::common::Ui;
use anyhow::{Context, Result};
use roadtrack::analysis::{self, Analysis, Site};
use roadtrack::calibration::Calibration;
use roadtrack::io::atomic::write_bytes_atomic;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Traffic analysis of tracks: counts across directional lines, turning movements (OD
/// between zones), speed distributions, headways and lane use, per class.
///
/// Writes counts.csv, od.csv, speeds.csv, headways.csv, lanes.csv and analysis.json into
/// the output folder and prints a summary.
#[derive(Debug, clap::Args)]
#[command(
    after_help = "Example:\n  roadtrack analyze traj.csv --calibration seq/calibration.toml --zones site.toml -o analysis/\n\nZones file (TOML; coordinates = \"ground\" (m, default) or \"image\" (px)):\n  [[line]]\n  name = \"stop line N\"\n  a = [-6.0, 10.0]\n  b = [6.0, 10.0]\n  [[zone]]\n  name = \"N\"\n  polygon = [[-6, 10], [6, 10], [6, 30], [-6, 30]]\n  [[lane]]\n  name = \"lane 1\"\n  polygon = [[0, 0], [700, 0], [700, 3.5], [0, 3.5]]\n  [stitch]\n  max_gap_s = 1.0\n  max_distance = 3.0"
)]
pub struct Args {
    /// Tracks: trajectories CSV (`.csv`) or MOTChallenge tracks (anything else).
    pub tracks: PathBuf,
    /// Calibration TOML; ground positions and speeds are computed from the image boxes.
    #[arg(long, value_name = "C.toml")]
    pub calibration: PathBuf,
    /// Lines, zones and lanes (TOML). Without it only speeds are reported.
    #[arg(long, value_name = "Z.toml")]
    pub zones: Option<PathBuf>,
    /// Output folder.
    #[arg(short, long, default_value = "analysis", value_parser = crate::common::folder_output)]
    pub output: PathBuf,
    /// Frame rate for MOTChallenge input (time = (frame − 1) / fps).
    #[arg(long, default_value_t = 10.0, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: f64,
    /// Half-width of the speed smoother's window, s.
    #[arg(long, default_value_t = 0.5, value_name = "S", value_parser = crate::flags::non_negative)]
    pub smooth_s: f64,
    /// Also write the trajectories on the ground as GeoJSON.
    #[arg(long, value_name = "F.geojson")]
    pub geojson: Option<PathBuf>,
    /// Print the analysis as JSON instead of a summary.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    let mut points = roadtrack::io::read_track_points(&args.tracks, args.fps)?;
    let calibration = Calibration::load(&args.calibration)?;
    roadtrack::analysis::ground::attach_calibration(&mut points, &calibration, None, args.smooth_s)
        .context("putting the tracks on the ground")?;
    let site: Site = match &args.zones {
        Some(p) => roadtrack::config::load_toml(p)?,
        None => Site::default(),
    };
    let result = analysis::analyze(&points, &site)?;
    write_outputs(&args.output, &result)?;
    if let Some(g) = &args.geojson {
        roadtrack::io::geojson::write_geojson(g, &points)?;
    }
    if args.json {
        crate::common::print_out(&format!("{}\n", serde_json::to_string_pretty(&result)?))?;
    } else {
        crate::common::print_out(&summary(&result))?;
    }
    ui.info(format!("analysis written to {}", args.output.display()));
    Ok(())
}

fn csv<T: serde::Serialize>(rows: &[T]) -> Result<String> {
    // The `csv` crate is not a CLI dependency; the rows are flat, so JSON objects in key
    // order give the header and values.
    let mut out = String::new();
    let values: Vec<serde_json::Map<String, serde_json::Value>> = rows
        .iter()
        .map(|r| match serde_json::to_value(r) {
            Ok(serde_json::Value::Object(m)) => Ok(m),
            _ => anyhow::bail!("row is not a flat object"),
        })
        .collect::<Result<_>>()?;
    let Some(first) = values.first() else {
        return Ok(out);
    };
    let keys: Vec<&String> = first.keys().collect();
    let _ = writeln!(
        out,
        "{}",
        keys.iter()
            .map(|k| k.as_str())
            .collect::<Vec<_>>()
            .join(",")
    );
    for v in &values {
        let line: Vec<String> = keys
            .iter()
            .map(|k| match &v[k.as_str()] {
                serde_json::Value::String(s) if s.contains([',', '"']) => {
                    format!("\"{}\"", s.replace('"', "\"\""))
                }
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Number(n) => n.as_f64().map_or(n.to_string(), |x| {
                    if x.fract() == 0.0 && x.abs() < 1e15 {
                        format!("{x:.0}")
                    } else {
                        format!("{x:.4}")
                    }
                }),
                other => other.to_string(),
            })
            .collect();
        let _ = writeln!(out, "{}", line.join(","));
    }
    Ok(out)
}

fn write_outputs(dir: &Path, a: &Analysis) -> Result<()> {
    write_bytes_atomic(&dir.join("counts.csv"), csv(&a.counts)?.as_bytes())?;
    write_bytes_atomic(&dir.join("od.csv"), csv(&a.od)?.as_bytes())?;
    write_bytes_atomic(
        &dir.join("od_incomplete.csv"),
        csv(&a.od_incomplete)?.as_bytes(),
    )?;
    write_bytes_atomic(&dir.join("speeds.csv"), csv(&a.speeds)?.as_bytes())?;
    write_bytes_atomic(&dir.join("headways.csv"), csv(&a.headways)?.as_bytes())?;
    write_bytes_atomic(&dir.join("lanes.csv"), csv(&a.lanes)?.as_bytes())?;
    write_bytes_atomic(
        &dir.join("analysis.json"),
        serde_json::to_string_pretty(a)?.as_bytes(),
    )?;
    Ok(())
}

fn summary(a: &Analysis) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} objects ({} track ids before stitching)",
        a.objects, a.tracks
    );
    for c in &a.counts {
        let _ = writeln!(
            s,
            "count  {:<16} {:<14} {:<11} {}",
            c.line, c.direction, c.class, c.count
        );
    }
    for o in &a.od {
        let _ = writeln!(
            s,
            "od     {:>8} → {:<8} {:<11} {}",
            o.origin, o.destination, o.class, o.count
        );
    }
    for o in &a.od_incomplete {
        let _ = writeln!(
            s,
            "incomplete {:>4} (first and last seen) {:<11} {}",
            o.origin, o.class, o.count
        );
    }
    for v in &a.speeds {
        let _ = writeln!(
            s,
            "speed  {:<11} n={:<4} mean {:.1} km/h, median {:.1}, p85 {:.1}",
            v.class,
            v.objects,
            v.mean_mps * 3.6,
            v.median_mps * 3.6,
            v.p85_mps * 3.6
        );
    }
    for h in &a.headways {
        let _ = writeln!(
            s,
            "headway {:<15} {:<14} n={:<4} mean {:.2} s, median {:.2} s, min {:.2} s",
            h.line, h.direction, h.n, h.mean_s, h.median_s, h.min_s
        );
    }
    for l in &a.lanes {
        let _ = writeln!(
            s,
            "lane   {:<16} {:<11} {} ({:.0} %)",
            l.lane,
            l.class,
            l.objects,
            l.share * 100.0
        );
    }
    s
}
