//! Plots as PNG or SVG (issue 8, part 4): trajectories over a background frame, time-space
//! diagrams of road scenes, and line charts of metric series.
//!
//! Drawing uses plotters without system fonts: the compiled-in DejaVu Sans
//! ([`crate::overlay::FONT_BYTES`]) is registered as plotters' `sans-serif`. The format
//! follows the output's extension (`.png` or `.svg`); files are written atomically and
//! the same input gives the same bytes.
//!
//! Background frames in SVG: plotters' SVG backend cannot draw bitmaps without a second
//! copy of the `image` crate, so the background is embedded after drawing, as one
//! `<image>` element holding a base64 PNG of the frame scaled to the plotting area, placed
//! right after the page's white fill and before every line. The SVG therefore stays one
//! self-contained file, with vector trajectories over the frame.

use crate::overlay::{FONT_BYTES, id_colour};
use image::RgbImage;
use plotters::coord::Shift;
use plotters::element::BitMapElement;
use plotters::prelude::*;
use roadtrack_core::error::{Error, Result};
use roadtrack_core::track_point::TrackPoint;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

pub use roadtrack_core::io::series::Series;

/// Size of [`line_chart`] images, px.
pub const LINE_CHART_SIZE: (u32, u32) = (900, 600);

/// The image coordinate along which a time-space diagram measures position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// Horizontal: `x_px`, or `x_m` with ground coordinates.
    #[default]
    #[cfg_attr(feature = "clap", value(help = "Horizontal (x_px or x_m)"))]
    X,
    /// Vertical: `y_px`, or `y_m` with ground coordinates.
    #[cfg_attr(feature = "clap", value(help = "Vertical (y_px or y_m)"))]
    Y,
}

/// How trajectory and time-space plots look.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlotConfig {
    /// Title above the plot; `None` for a default naming the plot kind.
    pub title: Option<String>,
    /// Image width, px; `None` derives it (trajectories: the scene's aspect ratio with the
    /// longer side of the plotting area 900 px; time-space: 1000 px).
    pub width_px: Option<u32>,
    /// Image height, px; `None` derives it (see `width_px`; time-space: 650 px).
    pub height_px: Option<u32>,
    /// Write each track's id next to its last point (default true).
    pub labels: bool,
    /// How far the background frame is faded towards white, in `[0, 1]` (default 0.35),
    /// so the lines stand out.
    pub background_fade: f32,
}

impl Default for PlotConfig {
    fn default() -> Self {
        Self {
            title: None,
            width_px: None,
            height_px: None,
            labels: true,
            // Choice: 0.35 keeps the scene recognisable while saturated lines stay legible.
            background_fade: 0.35,
        }
    }
}

impl PlotConfig {
    /// Fails when a value cannot be drawn.
    pub fn validate(&self) -> Result<()> {
        for (v, f) in [(self.width_px, "width_px"), (self.height_px, "height_px")] {
            if let Some(v) = v
                && !(200..=20_000).contains(&v)
            {
                return Err(Error::config(
                    "PlotConfig",
                    f,
                    format!("must be 200–20000 px, found {v}"),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.background_fade) {
            return Err(Error::config(
                "PlotConfig",
                "background_fade",
                format!("must be in [0, 1], found {}", self.background_fade),
            ));
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Png,
    Svg,
}

fn format_of(out: &Path) -> Result<Format> {
    match out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("png") => Ok(Format::Png),
        Some("svg") => Ok(Format::Svg),
        _ => Err(Error::Invalid(format!(
            "{}: plots are written as .png or .svg; choose one of these extensions",
            out.display()
        ))),
    }
}

/// Registers the compiled-in font as plotters' `sans-serif` (once per process).
fn register_fonts() -> Result<()> {
    static DONE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        [FontStyle::Normal, FontStyle::Bold]
            .into_iter()
            .all(|style| plotters::style::register_font("sans-serif", style, FONT_BYTES).is_ok())
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid(
            "the compiled-in font could not be registered for plotting".into(),
        ))
    }
}

/// Pixel rectangle of a chart's plotting area: x range, y range.
type PixelRect = (Range<i32>, Range<i32>);

/// Any displayable error as a message (plotters' error types differ per backend).
fn msg<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// Draws with `png` or `svg` by the extension of `out` and writes the file atomically. A
/// `background` (image, fade) is embedded in SVG output under the returned plotting area
/// (PNG drawers blit it themselves).
fn write_plot<P, S>(
    out: &Path,
    size: (u32, u32),
    background: Option<(&RgbImage, f32)>,
    png: P,
    svg: S,
) -> Result<()>
where
    P: FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<PixelRect, String>,
    S: FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<PixelRect, String>,
{
    let fail = |message: String| Error::Plot {
        path: out.to_owned(),
        message,
    };
    register_fonts()?;
    match format_of(out)? {
        Format::Png => {
            let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
                png(&root).map_err(fail)?;
                root.present().map_err(|e| fail(msg(e)))?;
            }
            let img = RgbImage::from_raw(size.0, size.1, buf)
                .ok_or_else(|| fail("plot buffer has the wrong size".into()))?;
            let bytes = roadtrack_core::io::sink::encode_png(&img, out)?;
            roadtrack_core::io::atomic::write_bytes_atomic(out, &bytes)
        }
        Format::Svg => {
            let mut text = String::new();
            let area = {
                let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                let area = svg(&root).map_err(fail)?;
                root.present().map_err(|e| fail(msg(e)))?;
                area
            };
            if let Some((bg, fade)) = background {
                text = embed_background(&text, &scaled(bg, &area, fade), &area, out)?;
            }
            roadtrack_core::io::atomic::write_bytes_atomic(out, text.as_bytes())
        }
    }
}

/// `bg` scaled to the rectangle's size.
fn scaled(bg: &RgbImage, (xs, ys): &PixelRect, fade: f32) -> RgbImage {
    let (w, h) = (
        (xs.end - xs.start).max(1) as u32,
        (ys.end - ys.start).max(1) as u32,
    );
    let mut img = image::imageops::resize(bg, w, h, image::imageops::FilterType::Triangle);
    for p in img.pixels_mut() {
        for c in &mut p.0 {
            *c = (f32::from(*c) * (1.0 - fade) + 255.0 * fade).round() as u8;
        }
    }
    img
}

/// Inserts `bg` (already scaled and faded) as a base64 PNG `<image>` after the first
/// element of `svg` (the page fill), so it lies under everything drawn after.
fn embed_background(svg: &str, bg: &RgbImage, area: &PixelRect, out: &Path) -> Result<String> {
    let png = roadtrack_core::io::sink::encode_png(bg, out)?;
    let element = format!(
        "<image x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" \
         href=\"data:image/png;base64,{}\"/>\n",
        area.0.start,
        area.1.start,
        bg.width(),
        bg.height(),
        base64(&png)
    );
    let bad = || Error::Plot {
        path: out.to_owned(),
        message: "unexpected SVG layout: no page fill to put the background after".into(),
    };
    let root_end = svg
        .find("<svg")
        .and_then(|i| svg[i..].find('>').map(|j| i + j + 1));
    let fill_end = root_end
        .and_then(|r| svg[r..].find("/>").map(|j| r + j + 2))
        .ok_or_else(bad)?;
    let mut s = String::with_capacity(svg.len() + element.len() + 1);
    s.push_str(&svg[..fill_end]);
    s.push('\n');
    s.push_str(&element);
    s.push_str(svg[fill_end..].trim_start_matches('\n'));
    Ok(s)
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(char::from(A[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// The colour of track `id` on a plot: its overlay colour ([`id_colour`]), darkened on
/// white so light hues (yellow, cyan) stay readable.
fn plot_colour(id: u64, on_white: bool) -> RGBColor {
    let [r, g, b] = id_colour(id).0;
    let k = if on_white { 0.78 } else { 1.0 };
    let d = |v: u8| (f64::from(v) * k).round() as u8;
    RGBColor(d(r), d(g), d(b))
}

/// Grid lines: light enough to stay behind the data.
const GRID: RGBColor = RGBColor(225, 225, 225);

/// Tick label formatter for an axis spanning `range`: as many decimals as the tick
/// spacing needs (about ten ticks per axis), so pixel axes read `100`, not `100.0`.
fn ticks(range: &Range<f64>) -> impl Fn(&f64) -> String + use<> {
    let step = ((range.end - range.start).abs() / 10.0).max(f64::MIN_POSITIVE);
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    move |v: &f64| format!("{v:.decimals$}")
}

/// Style of the id written next to a track's last point.
fn id_style() -> TextStyle<'static> {
    ("sans-serif", 14).into_font().color(&BLACK)
}

/// Offset in px of that id from the point: above and to the right, clear of the marker.
const ID_OFFSET: (i32, i32) = (6, -16);

/// Tracks as polylines, ids ascending, points in frame order.
fn tracks(points: &[TrackPoint]) -> BTreeMap<u64, Vec<&TrackPoint>> {
    let mut by_id: BTreeMap<u64, Vec<&TrackPoint>> = BTreeMap::new();
    for p in points {
        by_id.entry(p.id).or_default().push(p);
    }
    for v in by_id.values_mut() {
        v.sort_by_key(|p| p.frame);
    }
    by_id
}

/// `lo..hi` of the finite values, padded by 5 % of the span on both sides (by 1 when all
/// values are equal); `0..1` when there are none.
pub fn padded_range(values: impl IntoIterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return 0.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
    lo - pad..hi + pad
}

/// Plots every track's path (box centres, px) in image coordinates (y down), one colour
/// per id, a filled circle at the start, a triangle at the end and the id next to it,
/// over `background` when given (the frame's full extent is then the plot's extent; else
/// the tracks' bounding box). Writes PNG or SVG by the extension of `out`.
///
/// # Errors
/// An invalid config, an extension other than png/svg, a file that cannot be written.
pub fn plot_trajectories(
    points: &[TrackPoint],
    background: Option<&RgbImage>,
    config: &PlotConfig,
    out: &Path,
) -> Result<()> {
    config.validate()?;
    let by_id = tracks(points);
    let (xr, yr) = match background {
        Some(bg) => (0.0..f64::from(bg.width()), 0.0..f64::from(bg.height())),
        None => (
            padded_range(points.iter().map(|p| p.bbox.centre().x)),
            padded_range(points.iter().map(|p| p.bbox.centre().y)),
        ),
    };
    // Choice: plotting area with the scene's aspect ratio, longer side 900 px, plus room
    // for the title and the axes (the margins of `chart`).
    let (aw, ah) = {
        let (w, h) = (xr.end - xr.start, yr.end - yr.start);
        let s = 900.0 / w.max(h);
        ((w * s).round().max(150.0), (h * s).round().max(150.0))
    };
    let size = (
        config.width_px.unwrap_or(aw as u32 + 95),
        config.height_px.unwrap_or(ah as u32 + 105),
    );
    let title = config
        .title
        .clone()
        .unwrap_or_else(|| format!("Trajectories of {} tracks (● start, ▲ end)", by_id.len()));
    let faded = background.map(|bg| (bg, config.background_fade));
    let job = TrajectoryJob {
        by_id: &by_id,
        xr,
        yr,
        title: &title,
        labels: config.labels,
    };
    write_plot(
        out,
        size,
        faded,
        |root| job.draw(root, faded, true),
        |root| job.draw(root, faded, false),
    )
}

struct TrajectoryJob<'a> {
    by_id: &'a BTreeMap<u64, Vec<&'a TrackPoint>>,
    xr: Range<f64>,
    yr: Range<f64>,
    title: &'a str,
    labels: bool,
}

impl TrajectoryJob<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        background: Option<(&RgbImage, f32)>,
        blit: bool,
    ) -> Result<PixelRect, String> {
        root.fill(&WHITE).map_err(msg)?;
        // y runs down as in the image: the range is reversed.
        let mut chart = ChartBuilder::on(root)
            .caption(self.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(55)
            .build_cartesian_2d(self.xr.clone(), self.yr.end..self.yr.start)
            .map_err(msg)?;
        let area = chart.plotting_area().get_pixel_range();
        let on_white = background.is_none();
        if let (Some((bg, fade)), true) = (background, blit) {
            let img = scaled(bg, &area, fade);
            let (w, h) = img.dimensions();
            let elem = BitMapElement::with_owned_buffer(
                (area.0.start, area.1.start),
                (w, h),
                img.into_raw(),
            )
            .ok_or("background buffer has the wrong size")?;
            root.draw(&elem).map_err(msg)?;
        }
        let (fx, fy) = (ticks(&self.xr), ticks(&self.yr));
        let mut mesh = chart.configure_mesh();
        mesh.x_desc("x (px)")
            .y_desc("y (px)")
            .x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .bold_line_style(GRID)
            .light_line_style(TRANSPARENT);
        if !on_white {
            mesh.disable_mesh();
        }
        mesh.draw().map_err(msg)?;
        let width = if on_white { 2 } else { 3 };
        for (&id, track) in self.by_id {
            let colour = plot_colour(id, on_white);
            let line: Vec<(f64, f64)> = track
                .iter()
                .map(|p| {
                    let c = p.bbox.centre();
                    (c.x, c.y)
                })
                .collect();
            if line.len() >= 2 {
                chart
                    .draw_series(LineSeries::new(
                        line.iter().copied(),
                        colour.stroke_width(width),
                    ))
                    .map_err(msg)?;
            }
            if let (Some(&first), Some(&last)) = (line.first(), line.last()) {
                chart
                    .draw_series([Circle::new(first, 4, colour.filled())])
                    .map_err(msg)?;
                chart
                    .draw_series([TriangleMarker::new(last, 6, colour.filled())])
                    .map_err(msg)?;
                if self.labels {
                    chart
                        .draw_series([EmptyElement::at(last)
                            + Text::new(id.to_string(), ID_OFFSET, id_style())])
                        .map_err(msg)?;
                }
            }
        }
        Ok(area)
    }
}

/// Time-space diagram of a road scene: position along `axis` (ground metres when every
/// point has ground coordinates, else box-centre px) against time (s), one line per id.
/// Writes PNG or SVG by the extension of `out`.
///
/// # Errors
/// As [`plot_trajectories`].
pub fn plot_time_space(
    points: &[TrackPoint],
    axis: Axis,
    config: &PlotConfig,
    out: &Path,
) -> Result<()> {
    config.validate()?;
    let by_id = tracks(points);
    let (xr, yr, unit) = time_space_ranges(points, axis);
    let name = match axis {
        Axis::X => "x",
        Axis::Y => "y",
    };
    let size = (
        config.width_px.unwrap_or(1000),
        config.height_px.unwrap_or(650),
    );
    let title = config
        .title
        .clone()
        .unwrap_or_else(|| format!("Time-space diagram, {} tracks", by_id.len()));
    let y_desc = format!("{name} ({unit})");
    write_plot(
        out,
        size,
        None,
        |root| time_space_draw(root, &by_id, axis, &xr, &yr, &title, &y_desc, config.labels),
        |root| time_space_draw(root, &by_id, axis, &xr, &yr, &title, &y_desc, config.labels),
    )
}

/// The time range (s) and position range along `axis` a time-space diagram shows, both
/// padded by 5 %, and the position unit (`"m"` with ground coordinates, else `"px"`).
pub fn time_space_ranges(
    points: &[TrackPoint],
    axis: Axis,
) -> (Range<f64>, Range<f64>, &'static str) {
    let ground = !points.is_empty() && points.iter().all(|p| p.ground.is_some());
    let t = padded_range(points.iter().map(|p| p.time_s));
    let pos = padded_range(points.iter().map(|p| position(p, axis, ground)));
    (t, pos, if ground { "m" } else { "px" })
}

fn position(p: &TrackPoint, axis: Axis, ground: bool) -> f64 {
    match (p.ground, ground, axis) {
        (Some(g), true, Axis::X) => g.x_m,
        (Some(g), true, Axis::Y) => g.y_m,
        (_, _, Axis::X) => p.bbox.centre().x,
        (_, _, Axis::Y) => p.bbox.centre().y,
    }
}

#[allow(clippy::too_many_arguments)]
fn time_space_draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    by_id: &BTreeMap<u64, Vec<&TrackPoint>>,
    axis: Axis,
    xr: &Range<f64>,
    yr: &Range<f64>,
    title: &str,
    y_desc: &str,
    labels: bool,
) -> Result<PixelRect, String> {
    root.fill(&WHITE).map_err(msg)?;
    let ground = by_id.values().flatten().all(|p| p.ground.is_some()) && !by_id.is_empty();
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xr.clone(), yr.clone())
        .map_err(msg)?;
    let (fx, fy) = (ticks(xr), ticks(yr));
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc(y_desc)
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .bold_line_style(GRID)
        .light_line_style(TRANSPARENT)
        .draw()
        .map_err(msg)?;
    for (&id, track) in by_id {
        let colour = plot_colour(id, true);
        let line: Vec<(f64, f64)> = track
            .iter()
            .map(|p| (p.time_s, position(p, axis, ground)))
            .collect();
        chart
            .draw_series(LineSeries::new(
                line.iter().copied(),
                colour.stroke_width(2),
            ))
            .map_err(msg)?;
        if labels && let Some(&last) = line.last() {
            chart
                .draw_series([
                    EmptyElement::at(last) + Text::new(id.to_string(), ID_OFFSET, id_style())
                ])
                .map_err(msg)?;
        }
    }
    Ok(chart.plotting_area().get_pixel_range())
}

/// A chart of `series` as lines with point markers and a legend, [`LINE_CHART_SIZE`],
/// e.g. correct-match rate against Δt. Axis ranges cover every finite point (padded by
/// 5 %); non-finite points are skipped. Writes PNG or SVG by the extension of `out`.
///
/// # Errors
/// An extension other than png/svg, a file that cannot be written.
pub fn line_chart(
    series: &[Series],
    title: &str,
    x_label: &str,
    y_label: &str,
    out: &Path,
) -> Result<()> {
    let finite = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
    let all = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(finite)
    };
    let xr = padded_range(all().map(|p| p.0));
    let yr = padded_range(all().map(|p| p.1));
    write_plot(
        out,
        LINE_CHART_SIZE,
        None,
        |root| line_chart_draw(root, series, title, x_label, y_label, &xr, &yr),
        |root| line_chart_draw(root, series, title, x_label, y_label, &xr, &yr),
    )
}

/// Colours of chart series (Tableau 10): distinct, and readable on white.
const SERIES_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn line_chart_draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[Series],
    title: &str,
    x_label: &str,
    y_label: &str,
    xr: &Range<f64>,
    yr: &Range<f64>,
) -> Result<PixelRect, String> {
    root.fill(&WHITE).map_err(msg)?;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(xr.clone(), yr.clone())
        .map_err(msg)?;
    let (fx, fy) = (ticks(xr), ticks(yr));
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .bold_line_style(GRID)
        .light_line_style(TRANSPARENT)
        .draw()
        .map_err(msg)?;
    for (i, s) in series.iter().enumerate() {
        let colour = SERIES_COLOURS[i % SERIES_COLOURS.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|&(x, y)| x.is_finite() && y.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
            .map_err(msg)?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 22, y)], colour.stroke_width(3))
            });
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(msg)?;
    }
    if !series.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font(("sans-serif", 15))
            .draw()
            .map_err(msg)?;
    }
    Ok(chart.plotting_area().get_pixel_range())
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_core::ObjectClass;
    use roadtrack_core::geometry::BBox;
    use roadtrack_core::track_point::GroundState;

    fn point(frame: u32, id: u64, x: f64, y: f64) -> TrackPoint {
        TrackPoint {
            frame,
            time_s: f64::from(frame - 1) / 10.0,
            id,
            class: ObjectClass::Car,
            bbox: BBox::from_centre(roadtrack_core::Point::new(x, y), 10.0, 6.0),
            score: 1.0,
            ground: None,
        }
    }

    /// Three tracks crossing a 320 × 240 scene.
    fn scene() -> Vec<TrackPoint> {
        let mut v = Vec::new();
        for f in 1..=20u32 {
            let t = f64::from(f);
            v.push(point(f, 1, 20.0 + 14.0 * t, 60.0));
            v.push(point(f, 2, 300.0 - 12.0 * t, 150.0 + t));
            if f > 5 {
                v.push(point(f, 5, 160.0, 10.0 + 10.0 * t));
            }
        }
        v
    }

    fn tmp() -> tempfile::TempDir {
        tempfile::tempdir().expect("tempdir")
    }

    fn read(p: &Path) -> Vec<u8> {
        std::fs::read(p).expect("read plot")
    }

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }

    #[test]
    fn padded_range_covers_the_values() {
        assert_eq!(padded_range([1.0, 3.0, f64::NAN]), 0.9..3.1);
        assert_eq!(padded_range([2.0]), 1.0..3.0);
        assert_eq!(padded_range([]), 0.0..1.0);
    }

    #[test]
    fn png_line_chart_decodes_to_the_chart_size() -> Result<()> {
        let d = tmp();
        let out = d.path().join("rate.png");
        let series = vec![
            Series {
                label: "colour-bidirectional".into(),
                points: vec![(1.0, 0.98), (2.0, 0.95), (3.0, 0.9), (4.0, 0.82)],
            },
            Series {
                label: "unidirectional".into(),
                points: vec![(1.0, 0.9), (2.0, 0.8), (3.0, f64::NAN), (4.0, 0.6)],
            },
        ];
        line_chart(&series, "Correct-match rate", "Δt (frames)", "rate", &out)?;
        let img = image::open(&out)
            .map_err(|source| Error::Image {
                source,
                path: out.clone(),
            })?
            .to_rgb8();
        assert_eq!(img.dimensions(), LINE_CHART_SIZE);
        // The first series' colour is on the image (its line and markers).
        assert!(img.pixels().any(|p| p.0 == [31, 119, 180]));
        let first = read(&out);
        line_chart(&series, "Correct-match rate", "Δt (frames)", "rate", &out)?;
        assert_eq!(read(&out), first, "same input, same bytes");
        Ok(())
    }

    #[test]
    fn svg_line_chart_has_a_root_and_a_line_and_legend_entry_per_series() -> Result<()> {
        let d = tmp();
        let out = d.path().join("rate.svg");
        let series = vec![
            Series {
                label: "a".into(),
                points: vec![(0.0, 1.0), (1.0, 2.0)],
            },
            Series {
                label: "b".into(),
                points: vec![(0.0, 2.0), (1.0, 1.0)],
            },
        ];
        line_chart(&series, "t", "x", "y", &out)?;
        let text = String::from_utf8(read(&out)).expect("utf-8");
        assert!(text.contains("<svg"), "{text}");
        // Each series: its line plus its legend sample, in its colour.
        for c in ["#1F77B4", "#FF7F0E"] {
            let n = text
                .lines()
                .filter(|l| l.contains("<polyline") && l.to_ascii_uppercase().contains(c))
                .count();
            assert_eq!(n, 2, "{c}\n{text}");
        }
        Ok(())
    }

    #[test]
    fn svg_trajectories_have_one_polyline_per_id_in_its_colour() -> Result<()> {
        let d = tmp();
        let out = d.path().join("traj.svg");
        plot_trajectories(&scene(), None, &PlotConfig::default(), &out)?;
        let text = String::from_utf8(read(&out)).expect("utf-8");
        assert!(text.starts_with("<svg") || text.contains("<svg"), "{text}");
        // Track lines are 2 px wide; axes and ticks 1 px.
        let lines: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("<polyline") && l.contains("stroke-width=\"2\""))
            .collect();
        assert_eq!(lines.len(), 3, "{lines:#?}");
        for id in [1, 2, 5] {
            let RGBColor(r, g, b) = plot_colour(id, true);
            let hex = format!("#{r:02X}{g:02X}{b:02X}");
            assert!(
                lines.iter().any(|l| l.to_ascii_uppercase().contains(&hex)),
                "id {id} colour {hex} missing"
            );
        }
        assert!(!text.contains("<image"), "no background was given");
        Ok(())
    }

    #[test]
    fn png_trajectories_over_a_background_have_the_requested_size_and_show_the_frame() -> Result<()>
    {
        let d = tmp();
        let out = d.path().join("traj.png");
        let bg = RgbImage::from_pixel(320, 240, image::Rgb([0, 90, 0]));
        let config = PlotConfig {
            width_px: Some(640),
            height_px: Some(520),
            ..PlotConfig::default()
        };
        plot_trajectories(&scene(), Some(&bg), &config, &out)?;
        let img = image::open(&out)
            .map_err(|source| Error::Image {
                source,
                path: out.clone(),
            })?
            .to_rgb8();
        assert_eq!(img.dimensions(), (640, 520));
        // The faded background colour: 0.65·(0, 90, 0) + 0.35·255.
        let faded = [89, 148, 89];
        assert!(img.pixels().filter(|p| p.0 == faded).count() > 10_000);
        // Track 1's colour (undarkened over a background) is drawn.
        let RGBColor(r, g, b) = plot_colour(1, false);
        assert!(img.pixels().any(|p| p.0 == [r, g, b]));
        Ok(())
    }

    #[test]
    fn svg_trajectories_embed_the_background_under_the_lines() -> Result<()> {
        let d = tmp();
        let out = d.path().join("traj.svg");
        let bg = RgbImage::from_pixel(320, 240, image::Rgb([0, 90, 0]));
        plot_trajectories(&scene(), Some(&bg), &PlotConfig::default(), &out)?;
        let text = String::from_utf8(read(&out)).expect("utf-8");
        let image_at = text.find("<image").expect("background embedded");
        let first_line = text.find("<polyline").expect("lines");
        assert!(image_at < first_line);
        assert!(text.contains("href=\"data:image/png;base64,iVBORw0KGgo"));
        Ok(())
    }

    #[test]
    fn time_space_ranges_cover_the_data_in_pixels_or_metres() {
        let pts = scene();
        let (t, x, unit) = time_space_ranges(&pts, Axis::X);
        assert_eq!(unit, "px");
        for p in &pts {
            assert!(
                t.contains(&p.time_s) && x.contains(&p.bbox.centre().x),
                "{p:?}"
            );
        }
        let (_, y, _) = time_space_ranges(&pts, Axis::Y);
        assert!(y.start < 70.0 && y.end > 210.0, "{y:?}");
        let ground: Vec<_> = pts
            .iter()
            .map(|p| TrackPoint {
                ground: Some(GroundState {
                    x_m: p.bbox.centre().x / 10.0,
                    y_m: 0.0,
                    speed_mps: 0.0,
                    heading_deg: 0.0,
                }),
                ..p.clone()
            })
            .collect();
        let (_, xm, unit) = time_space_ranges(&ground, Axis::X);
        assert_eq!(unit, "m");
        assert!(xm.start <= 3.4 && xm.end >= 30.0 && xm.end < 40.0, "{xm:?}");
    }

    #[test]
    fn time_space_diagram_is_written_as_png_and_svg() -> Result<()> {
        let d = tmp();
        for name in ["ts.png", "ts.svg"] {
            let out = d.path().join(name);
            plot_time_space(&scene(), Axis::X, &PlotConfig::default(), &out)?;
            assert!(read(&out).len() > 1000, "{name}");
        }
        let img = image::open(d.path().join("ts.png")).map_err(|source| Error::Image {
            source,
            path: "ts.png".into(),
        })?;
        assert_eq!((img.width(), img.height()), (1000, 650));
        let svg = String::from_utf8(read(&d.path().join("ts.svg"))).expect("utf-8");
        let tracks = svg
            .lines()
            .filter(|l| l.contains("<polyline") && l.contains("stroke-width=\"2\""))
            .count();
        assert_eq!(tracks, 3);
        assert!(svg.contains("time (s)") && svg.contains("x (px)"));
        Ok(())
    }

    #[test]
    fn other_extensions_are_refused() {
        let d = tmp();
        let e = line_chart(&[], "t", "x", "y", &d.path().join("a.jpg")).expect_err("jpg");
        assert!(e.to_string().contains(".png or .svg"), "{e}");
    }
}
