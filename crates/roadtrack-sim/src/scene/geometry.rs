//! Ground-plane geometry of the scenes: polylines with offsets, painted areas.

/// A ground point or vector `[x_m, y_m]`.
pub type Vec2 = [f64; 2];

pub(super) fn sub(a: Vec2, b: Vec2) -> Vec2 {
    [a[0] - b[0], a[1] - b[1]]
}

pub(super) fn norm(a: Vec2) -> f64 {
    a[0].hypot(a[1])
}

/// Rotates `p` by `k` quarter turns counter-clockwise.
pub(super) fn rot(p: Vec2, k: usize) -> Vec2 {
    match k % 4 {
        0 => p,
        1 => [-p[1], p[0]],
        2 => [-p[0], -p[1]],
        _ => [p[1], -p[0]],
    }
}

/// A path on the ground, parametrised by arc length `s` from its first point.
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    points: Vec<Vec2>,
    cum_m: Vec<f64>,
}

impl Polyline {
    /// A path through `points` (consecutive duplicates are dropped).
    pub fn new(points: Vec<Vec2>) -> Self {
        let mut pts: Vec<Vec2> = Vec::with_capacity(points.len());
        for p in points {
            if pts.last().is_none_or(|q| norm(sub(p, *q)) > 1e-9) {
                pts.push(p);
            }
        }
        let mut cum_m = Vec::with_capacity(pts.len());
        let mut acc = 0.0;
        for (i, p) in pts.iter().enumerate() {
            if i > 0 {
                acc += norm(sub(*p, pts[i - 1]));
            }
            cum_m.push(acc);
        }
        Self { points: pts, cum_m }
    }

    /// The vertices.
    pub fn points(&self) -> &[Vec2] {
        &self.points
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        self.cum_m.last().copied().unwrap_or(0.0)
    }

    /// Arc length of vertex `i`, m.
    pub fn vertex_s(&self, i: usize) -> f64 {
        self.cum_m.get(i).copied().unwrap_or(0.0)
    }

    /// Position and heading (radians, ccw from `+x`) at arc length `s` (clamped to the
    /// path; beyond the ends the path is extended straight).
    pub fn at(&self, s: f64) -> (Vec2, f64) {
        let n = self.points.len();
        if n < 2 {
            return (self.points.first().copied().unwrap_or([0.0, 0.0]), 0.0);
        }
        let i = match self.cum_m.partition_point(|&c| c <= s) {
            0 => 0,
            k if k >= n => n - 2,
            k => k - 1,
        };
        let (a, b) = (self.points[i], self.points[i + 1]);
        let d = sub(b, a);
        let len = norm(d);
        let t = (s - self.cum_m[i]) / len;
        ([a[0] + d[0] * t, a[1] + d[1] * t], d[1].atan2(d[0]))
    }

    /// The path shifted `d` metres to its left (negative: right), with mitred corners so
    /// the shifted path stays parallel to every leg.
    pub fn offset(&self, d: f64) -> Polyline {
        let n = self.points.len();
        if n < 2 || d == 0.0 {
            return self.clone();
        }
        let normal = |i: usize| {
            let v = sub(self.points[i + 1], self.points[i]);
            let l = norm(v);
            [-v[1] / l, v[0] / l]
        };
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let m = if i == 0 {
                normal(0)
            } else if i == n - 1 {
                normal(n - 2)
            } else {
                let (a, b) = (normal(i - 1), normal(i));
                let s = [a[0] + b[0], a[1] + b[1]];
                let dot = 1.0 + a[0] * b[0] + a[1] * b[1];
                if dot < 1e-6 {
                    a
                } else {
                    [s[0] / dot, s[1] / dot]
                }
            };
            out.push([self.points[i][0] + m[0] * d, self.points[i][1] + m[1] * d]);
        }
        Polyline::new(out)
    }
}

/// What a patch of ground is, for the renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    /// Road surface.
    Asphalt,
    /// Paved footway.
    Sidewalk,
    /// Concrete kerb line.
    Kerb,
    /// White paint (lane lines, stop lines, zebra stripes).
    WhitePaint,
    /// Bare ground / gravel verge.
    Verge,
    /// Lawn or field.
    Grass,
    /// A flat-roofed building lot, seen as plain concrete.
    Lot,
}

/// A convex ground polygon of one surface. Later areas are painted over earlier ones.
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// Vertices, counter-clockwise or clockwise, convex.
    pub polygon: Vec<Vec2>,
    /// Surface.
    pub surface: Surface,
    /// Bounding box `[xmin, ymin, xmax, ymax]`.
    pub bbox: [f64; 4],
}

impl Area {
    pub(super) fn new(polygon: Vec<Vec2>, surface: Surface) -> Self {
        let mut bbox = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in &polygon {
            bbox[0] = bbox[0].min(p[0]);
            bbox[1] = bbox[1].min(p[1]);
            bbox[2] = bbox[2].max(p[0]);
            bbox[3] = bbox[3].max(p[1]);
        }
        Self {
            polygon,
            surface,
            bbox,
        }
    }

    /// An axis-aligned rectangle.
    pub(super) fn rect(x0: f64, y0: f64, x1: f64, y1: f64, surface: Surface) -> Self {
        let (x0, x1) = (x0.min(x1), x0.max(x1));
        let (y0, y1) = (y0.min(y1), y0.max(y1));
        Self::new(vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]], surface)
    }

    /// Whether `p` is inside (boundary included).
    pub fn contains(&self, p: Vec2) -> bool {
        p[0] >= self.bbox[0]
            && p[0] <= self.bbox[2]
            && p[1] >= self.bbox[1]
            && p[1] <= self.bbox[3]
            && convex_contains(&self.polygon, p)
    }
}

/// Whether convex polygon `poly` contains `p` (boundary included).
pub fn convex_contains(poly: &[Vec2], p: Vec2) -> bool {
    let n = poly.len();
    let mut sign = 0.0f64;
    for i in 0..n {
        let a = poly[i];
        let b = poly[(i + 1) % n];
        let c = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        if c.abs() < 1e-12 {
            continue;
        }
        if sign == 0.0 {
            sign = c.signum();
        } else if c.signum() != sign {
            return false;
        }
    }
    true
}

/// Dashed line along `x` from `x0` to `x1` at `y`, `width` wide.
pub(super) fn dashes(
    areas: &mut Vec<Area>,
    x0: f64,
    x1: f64,
    y: f64,
    width: f64,
    dash: f64,
    gap: f64,
) {
    let mut x = x0;
    while x < x1 {
        let e = (x + dash).min(x1);
        areas.push(Area::rect(
            x,
            y - width / 2.0,
            e,
            y + width / 2.0,
            Surface::WhitePaint,
        ));
        x += dash + gap;
    }
}
