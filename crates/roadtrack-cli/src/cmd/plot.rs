//! `roadtrack plot`: trajectory plots, time-space diagrams and metric charts.

use crate::common::Ui;
use anyhow::{Context, Result, bail};
use roadtrack::io::{read_track_points, series::read_series, source};
use roadtrack_viz::plot::{Axis, PlotConfig, line_chart, plot_time_space, plot_trajectories};
use std::path::{Path, PathBuf};

/// Plot trajectories (over a background frame, or as a time-space diagram), or a metric
/// chart from any CSV table. PNG or SVG by the output's extension.
///
/// Trajectory plots draw each track's box centres in image coordinates, one colour per
/// id, a dot at the start and a triangle at the end. In SVG a background frame is embedded
/// as one PNG image under the vector lines.
#[derive(Debug, clap::Args)]
#[command(after_help = "Examples:\n  \
    roadtrack plot tracks.txt --background seq/ -o trajectories.png\n  \
    roadtrack plot trajectories.csv --time-space --axis x -o time_space.svg\n  \
    roadtrack plot --series sweep.csv --x dt --y correct_rate --group variant -o rate.png")]
pub struct Args {
    /// Tracks: `.txt` = MOTChallenge tracks file, `.csv` = trajectories CSV.
    #[arg(required_unless_present = "series", conflicts_with = "series")]
    pub tracks: Option<PathBuf>,
    /// Output plot, .png or .svg.
    #[arg(short, long, default_value = "plot.png", value_name = "PLOT", value_parser = crate::common::plot_output)]
    pub output: PathBuf,
    /// Background: an image file, or a video / image folder / sequence whose first frame
    /// is used. Sets the plot's extent to the frame.
    #[arg(long, value_name = "IMG", conflicts_with = "time_space")]
    pub background: Option<PathBuf>,
    /// Draw a time-space diagram (position along --axis against time) instead.
    #[arg(long)]
    pub time_space: bool,
    /// Position axis of the time-space diagram (ground metres when the trajectories CSV
    /// has them, else pixels).
    #[arg(long, value_enum, default_value_t = Axis::X, requires = "time_space")]
    pub axis: Axis,
    /// Frame rate for the times of a MOTChallenge tracks file, frames/s.
    #[arg(long, default_value_t = 10.0, value_name = "FPS", value_parser = roadtrack::limits::parse_fps)]
    pub fps: f64,
    /// Chart the columns of this CSV table instead (e.g. a sweep table).
    #[arg(
        long,
        value_name = "F.csv",
        requires_all = ["x", "y"],
        conflicts_with_all = ["background", "time_space", "fps", "width", "height", "no_labels"]
    )]
    pub series: Option<PathBuf>,
    /// Column for the x axis (with --series).
    #[arg(long, value_name = "COL", requires = "series")]
    pub x: Option<String>,
    /// Column for the y axis (with --series).
    #[arg(long, value_name = "COL", requires = "series")]
    pub y: Option<String>,
    /// Column whose values split the rows into one line each (with --series).
    #[arg(long, value_name = "COL", requires = "series")]
    pub group: Option<String>,
    /// Title (default: names the plot kind).
    #[arg(long)]
    pub title: Option<String>,
    /// Image width, px (trajectory and time-space plots).
    #[arg(long, value_name = "PX")]
    pub width: Option<u32>,
    /// Image height, px (trajectory and time-space plots).
    #[arg(long, value_name = "PX")]
    pub height: Option<u32>,
    /// Leave out the track ids at the ends of the lines.
    #[arg(long)]
    pub no_labels: bool,
}

pub fn run(args: Args, ui: &Ui) -> Result<()> {
    if let Some(table) = &args.series {
        let (Some(x), Some(y)) = (&args.x, &args.y) else {
            bail!("--series needs --x COL and --y COL");
        };
        let series = read_series(table, x, y, args.group.as_deref())?;
        let title = args
            .title
            .clone()
            .unwrap_or_else(|| format!("{y} against {x}"));
        line_chart(&series, &title, x, y, &args.output)?;
        ui.info(format!(
            "{} series from {} → {}",
            series.len(),
            table.display(),
            args.output.display()
        ));
        return Ok(());
    }
    let Some(tracks_path) = &args.tracks else {
        bail!("give a tracks file, or --series F.csv");
    };
    let config = PlotConfig {
        title: args.title.clone(),
        width_px: args.width,
        height_px: args.height,
        labels: !args.no_labels,
        ..PlotConfig::default()
    };
    crate::flags::check_overrides(
        config.validate(),
        &[
            ("width_px", "--width", true),
            ("height_px", "--height", true),
        ],
        None,
    )?;
    let points = read_track_points(tracks_path, args.fps)?;
    if args.time_space {
        plot_time_space(&points, args.axis, &config, &args.output)?;
    } else {
        let background = match &args.background {
            Some(p) => Some(load_background(p)?),
            None => None,
        };
        plot_trajectories(&points, background.as_ref(), &config, &args.output)?;
    }
    ui.info(format!(
        "{} points of {} → {}",
        points.len(),
        tracks_path.display(),
        args.output.display()
    ));
    Ok(())
}

/// An image file, or the first frame of any frame source.
fn load_background(path: &Path) -> Result<image::RgbImage> {
    let is_image = path.is_file()
        && path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| ["png", "jpg", "jpeg"].contains(&e.to_ascii_lowercase().as_str()));
    if is_image {
        return Ok(image::open(path)
            .with_context(|| format!("reading background {}", path.display()))?
            .to_rgb8());
    }
    let mut frames = source::open(path, &roadtrack::io::SourceOptions::default())?;
    match frames.next() {
        Some(f) => Ok(f?.image),
        None => bail!("{}: no frames to use as background", path.display()),
    }
}
