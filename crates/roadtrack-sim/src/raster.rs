//! Scan conversion and polygon geometry for the renderer ([`crate::render`]): convex
//! fills at pixel centres, polygon area, clipping to the frame and convex hulls.

/// Fills the convex image polygon `poly` (`u, v, q`) over a `w × h` raster: calls
/// `plot(pixel index, q at the pixel centre)` for every pixel whose centre is inside.
pub(crate) fn fill_convex(
    poly: &[(f64, f64, f64)],
    w: usize,
    h: usize,
    mut plot: impl FnMut(usize, f32),
) {
    let n = poly.len();
    if n < 3 {
        return;
    }
    // Depth plane q = a·u + b·v + c from the widest triangle fan.
    let (p0, mut best, mut area) = (poly[0], (1, 2), 0.0);
    for i in 1..n - 1 {
        let (p1, p2) = (poly[i], poly[i + 1]);
        let cr = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
        if cr.abs() > area {
            area = cr.abs();
            best = (i, i + 1);
        }
    }
    if area < 1e-9 {
        return;
    }
    let (p1, p2) = (poly[best.0], poly[best.1]);
    let det = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
    let qa = ((p1.2 - p0.2) * (p2.1 - p0.1) - (p2.2 - p0.2) * (p1.1 - p0.1)) / det;
    let qb = ((p1.0 - p0.0) * (p2.2 - p0.2) - (p2.0 - p0.0) * (p1.2 - p0.2)) / det;
    let qc = p0.2 - qa * p0.0 - qb * p0.1;
    let ymin = poly.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let ymax = poly.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let j0 = (ymin - 0.5).ceil().max(0.0) as usize;
    let j1 = ((ymax - 0.5).floor()).min(h as f64 - 1.0);
    if j1 < 0.0 {
        return;
    }
    for j in j0..=(j1 as usize) {
        let yc = j as f64 + 0.5;
        let (mut xl, mut xr) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..n {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            if (a.1 <= yc && yc < b.1) || (b.1 <= yc && yc < a.1) {
                let x = a.0 + (yc - a.1) * (b.0 - a.0) / (b.1 - a.1);
                xl = xl.min(x);
                xr = xr.max(x);
            }
        }
        if xl > xr {
            continue;
        }
        let i0 = (xl - 0.5).ceil().max(0.0) as usize;
        let i1 = ((xr - 0.5).ceil()).min(w as f64);
        if i1 <= 0.0 {
            continue;
        }
        let row = j * w;
        for i in i0..(i1 as usize) {
            let q = qa * (i as f64 + 0.5) + qb * yc + qc;
            plot(row + i, q as f32);
        }
    }
}

/// Share of the convex hull of `pts` inside `[0, w] × [0, h]`, by area; 1 for a hull of no
/// area (a point or a line: nothing to cut).
// Choice: the hull of the projected corners, not the drawn pixels: the pixels outside the
// image are never drawn, and a vehicle's or a walker's outline is close to its hull.
pub(crate) fn share_in_frame(pts: Vec<[f64; 2]>, w: f64, h: f64) -> f64 {
    let hull = convex_hull(pts);
    let whole = polygon_area(&hull);
    if whole <= 0.0 {
        return 1.0;
    }
    (polygon_area(&clip_to_rect(&hull, w, h)) / whole).clamp(0.0, 1.0)
}

/// Shoelace area (absolute) of a simple polygon.
pub(crate) fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    if n < 3 {
        return 0.0;
    }
    let twice: f64 = (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

/// Sutherland–Hodgman: the convex polygon `poly` clipped to `[0, w] × [0, h]`.
fn clip_to_rect(poly: &[[f64; 2]], w: f64, h: f64) -> Vec<[f64; 2]> {
    // Each edge as (axis, bound, keep where coordinate ≥ bound?).
    let edges = [(0, 0.0, true), (0, w, false), (1, 0.0, true), (1, h, false)];
    let mut out = poly.to_vec();
    for (axis, bound, above) in edges {
        let inside = |p: &[f64; 2]| {
            if above {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        let input = std::mem::take(&mut out);
        let n = input.len();
        for i in 0..n {
            let (a, b) = (input[i], input[(i + 1) % n]);
            let (ia, ib) = (inside(&a), inside(&b));
            if ia {
                out.push(a);
            }
            if ia != ib {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

/// Convex hull (Andrew's monotone chain), counter-clockwise.
pub(crate) fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut lower: Vec<[f64; 2]> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<[f64; 2]> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

#[cfg(test)]
mod tests {
    use super::*;
    use roadtrack_core::rng::{Stream, rng_for};

    #[test]
    fn share_in_frame_matches_a_grid_count() {
        // Hulls of random points around a 100 × 80 frame, against counting a 0.25 px grid.
        use rand::RngExt as _;
        let mut rng = rng_for(7, Stream::Render, 0);
        let mut next = || rng.random::<f64>();
        for _ in 0..20 {
            let pts: Vec<[f64; 2]> = (0..6)
                .map(|_| [next() * 200.0 - 50.0, next() * 160.0 - 40.0])
                .collect();
            let hull = convex_hull(pts.clone());
            let inside_hull = |x: f64, y: f64| {
                (0..hull.len()).all(|i| {
                    let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
                    (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0.0
                })
            };
            let (mut all, mut kept) = (0u32, 0u32);
            for i in 0..800 {
                for j in 0..640 {
                    let (x, y) = (
                        -50.0 + (f64::from(i) + 0.5) * 0.25,
                        -40.0 + (f64::from(j) + 0.5) * 0.25,
                    );
                    if inside_hull(x, y) {
                        all += 1;
                        kept += u32::from((0.0..100.0).contains(&x) && (0.0..80.0).contains(&y));
                    }
                }
            }
            let want = f64::from(kept) / f64::from(all);
            let got = share_in_frame(pts, 100.0, 80.0);
            assert!((got - want).abs() < 0.01, "{got} against {want}");
        }
        // Inside, outside, half.
        let sq = |x0: f64| vec![[x0, 10.0], [x0 + 20.0, 10.0], [x0 + 20.0, 30.0], [x0, 30.0]];
        assert_eq!(share_in_frame(sq(40.0), 100.0, 80.0), 1.0);
        assert_eq!(share_in_frame(sq(200.0), 100.0, 80.0), 0.0);
        assert!((share_in_frame(sq(-10.0), 100.0, 80.0) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn fill_covers_pixel_centres_of_a_rectangle_exactly() {
        let mut n = 0;
        let poly = [
            (2.0, 3.0, 1.0),
            (12.0, 3.0, 1.0),
            (12.0, 8.0, 1.0),
            (2.0, 8.0, 1.0),
        ];
        fill_convex(&poly, 20, 20, |_, q| {
            n += 1;
            assert!((q - 1.0).abs() < 1e-6);
        });
        assert_eq!(n, 50);
    }
}
