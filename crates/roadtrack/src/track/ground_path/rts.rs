//! A constant-velocity Rauch–Tung–Striebel smoother on the ground plane: the positions of
//! one vehicle or walker, each measured with its own covariance (or not at all), smoothed over the
//! whole track.
//!
//! State `[x, y, vx, vy]` (m, m/s); between times `t` and `t + dt` it moves at its velocity,
//! disturbed by white acceleration noise of spectral density `q` (m²/s³; Bar-Shalom, Li and
//! Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001, §6.2.2):
//!
//! ```text
//! F = [[I, dt·I], [0, I]],   Q = q · [[dt³/3·I, dt²/2·I], [dt²/2·I, dt·I]]
//! ```
//!
//! The Kalman filter runs forward; the smoother's pass back gives each state the estimate
//! given every measurement, before and after (Rauch, Tung and Striebel, 1965).

use nalgebra::{Matrix2, Matrix2x4, Matrix4, Vector2, Vector4};

/// A measured ground position (m) and its covariance (m²).
pub(crate) type Fix = (Vector2<f64>, Matrix2<f64>);

/// Prior variance of the first position, in units of its measurement's variance, and of the
/// velocity, (m/s)²: wide enough that the measurements decide.
const PRIOR_POSITION: f64 = 100.0;
const PRIOR_VELOCITY: f64 = 1.0e4;

fn transition(dt: f64, q: f64) -> (Matrix4<f64>, Matrix4<f64>) {
    let mut f = Matrix4::identity();
    f[(0, 2)] = dt;
    f[(1, 3)] = dt;
    let (a, b, c) = (dt.powi(3) / 3.0, dt.powi(2) / 2.0, dt);
    let mut m = Matrix4::zeros();
    for k in 0..2 {
        m[(k, k)] = a;
        m[(k, k + 2)] = b;
        m[(k + 2, k)] = b;
        m[(k + 2, k + 2)] = c;
    }
    (f, m * q)
}

/// The smoothed states at `times` (increasing, s) given `fixes` (one per time, `None` where
/// nothing was measured), and the log-likelihood of the fixes under the model (the sum of
/// the innovations' normal log densities); `None` when nothing was measured at all or a
/// covariance could not be inverted.
pub(crate) fn smooth(
    times: &[f64],
    fixes: &[Option<Fix>],
    q: f64,
) -> Option<(Vec<Vector4<f64>>, f64)> {
    debug_assert_eq!(times.len(), fixes.len());
    let (z0, r0) = fixes.iter().find_map(|z| *z)?;
    let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
    let mut x = Vector4::new(z0.x, z0.y, 0.0, 0.0);
    let mut p = Matrix4::from_diagonal(&Vector4::new(
        PRIOR_POSITION * r0[(0, 0)],
        PRIOR_POSITION * r0[(1, 1)],
        PRIOR_VELOCITY,
        PRIOR_VELOCITY,
    ));
    let n = times.len();
    // Forward: predicted and filtered moments, and each step's transition.
    let mut predicted = Vec::with_capacity(n);
    let mut filtered = Vec::with_capacity(n);
    let mut steps = Vec::with_capacity(n);
    let mut log_likelihood = 0.0;
    for i in 0..n {
        // Choice: the prior is on the first point's state, centred on the first measured
        // position with no velocity; it is wide, so the measurements decide.
        let (f, qm) = transition(if i == 0 { 0.0 } else { times[i] - times[i - 1] }, q);
        if i > 0 {
            x = f * x;
            p = f * p * f.transpose() + qm;
        }
        predicted.push((x, p));
        steps.push(f);
        if let Some((z, r)) = fixes[i] {
            let s = h * p * h.transpose() + r;
            let s_inv = s.try_inverse()?;
            let nu = z - h * x;
            log_likelihood -= 0.5
                * ((nu.transpose() * s_inv * nu)[(0, 0)]
                    + s.determinant().ln()
                    + 2.0 * std::f64::consts::TAU.ln());
            let k = p * h.transpose() * s_inv;
            x += k * nu;
            p = (Matrix4::identity() - k * h) * p;
        }
        filtered.push((x, p));
    }
    // Back: x_s[i] = x_f[i] + C (x_s[i+1] − x_p[i+1]), C = P_f[i] Fᵀ P_p[i+1]⁻¹.
    let mut out = vec![Vector4::zeros(); n];
    out[n - 1] = filtered[n - 1].0;
    for i in (0..n - 1).rev() {
        let (xf, pf) = filtered[i];
        let (xp, pp) = predicted[i + 1];
        let c = pf * steps[i + 1].transpose() * pp.try_inverse()?;
        out[i] = xf + c * (out[i + 1] - xp);
    }
    Some((out, log_likelihood))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// The smoother's states are the joint maximum a posteriori solution: the minimum of
    /// Σ |z_i − H x_i|²_{R_i⁻¹} + Σ |x_{i+1} − F x_i|²_{Q⁻¹} + the prior on the first
    /// measured state, solved here as one dense least-squares problem.
    #[test]
    fn the_smoother_gives_the_batch_least_squares_states() {
        let times = [0.0, 0.1, 0.3, 0.4, 0.45, 0.6, 0.9];
        let z = |x: f64, y: f64, sx: f64, sy: f64, c: f64| {
            Some((Vector2::new(x, y), Matrix2::new(sx * sx, c, c, sy * sy)))
        };
        let fixes = [
            None,
            z(1.0, 2.0, 0.3, 0.5, 0.05),
            z(1.9, 2.1, 0.2, 0.4, -0.02),
            None,
            z(3.1, 2.6, 1.0, 0.3, 0.0),
            z(3.3, 2.9, 0.4, 0.4, 0.1),
            z(5.0, 3.0, 0.5, 0.2, 0.0),
        ];
        let q = 0.7;
        let (got, _) = smooth(&times, &fixes, q).expect("measured");
        // Information form: A x = b over the stacked states.
        let n = times.len();
        let mut a = DMatrix::<f64>::zeros(4 * n, 4 * n);
        let mut b = DVector::<f64>::zeros(4 * n);
        let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        let add = |a: &mut DMatrix<f64>, i: usize, j: usize, m: &Matrix4<f64>| {
            for r in 0..4 {
                for c in 0..4 {
                    a[(4 * i + r, 4 * j + c)] += m[(r, c)];
                }
            }
        };
        // The prior on the first state, centred on the first measured position.
        let (z0, r0) = fixes[1].unwrap();
        let p0 = Matrix4::from_diagonal(&Vector4::new(
            PRIOR_POSITION * r0[(0, 0)],
            PRIOR_POSITION * r0[(1, 1)],
            PRIOR_VELOCITY,
            PRIOR_VELOCITY,
        ));
        let p0i = p0.try_inverse().unwrap();
        add(&mut a, 0, 0, &p0i);
        let rhs = p0i * Vector4::new(z0.x, z0.y, 0.0, 0.0);
        for r in 0..4 {
            b[r] += rhs[r];
        }
        for (i, fix) in fixes.iter().enumerate() {
            if let Some((zi, ri)) = fix {
                let w = ri.try_inverse().unwrap();
                add(&mut a, i, i, &(h.transpose() * w * h));
                let rhs = h.transpose() * w * zi;
                for r in 0..4 {
                    b[4 * i + r] += rhs[r];
                }
            }
        }
        for i in 0..n - 1 {
            let (f, qm) = transition(times[i + 1] - times[i], q);
            let w = qm.try_inverse().unwrap();
            // |x_{i+1} − F x_i|²_W: blocks (i,i) FᵀWF, (i,i+1) −FᵀW, (i+1,i) −WF, (i+1,i+1) W.
            add(&mut a, i, i, &(f.transpose() * w * f));
            add(&mut a, i, i + 1, &(-(f.transpose() * w)));
            add(&mut a, i + 1, i, &(-(w * f)));
            add(&mut a, i + 1, i + 1, &w);
        }
        let want = a.lu().solve(&b).expect("a positive definite system");
        for (i, g) in got.iter().enumerate() {
            for r in 0..4 {
                let w = want[4 * i + r];
                assert!(
                    (g[r] - w).abs() < 1e-6 * (1.0 + w.abs()),
                    "state {i}[{r}]: {g} {w}"
                );
            }
        }
    }

    /// Exact measurements of a uniform motion, with almost no process noise, give that
    /// motion back, the velocity included, at the unmeasured times too.
    #[test]
    fn a_uniform_motion_is_recovered() {
        let times: Vec<f64> = (0..30).map(|i| f64::from(i) * 0.1).collect();
        let r = Matrix2::identity() * 0.01;
        let fixes: Vec<Option<Fix>> = times
            .iter()
            .enumerate()
            .map(|(i, t)| (i % 4 != 2).then(|| (Vector2::new(3.0 + 12.0 * t, -1.0 - 0.5 * t), r)))
            .collect();
        let (got, _) = smooth(&times, &fixes, 1e-6).expect("measured");
        for (t, s) in times.iter().zip(&got) {
            assert!((s[0] - (3.0 + 12.0 * t)).abs() < 1e-3, "{t}: {s}");
            assert!((s[1] - (-1.0 - 0.5 * t)).abs() < 1e-3, "{t}: {s}");
            assert!(
                (s[2] - 12.0).abs() < 1e-2 && (s[3] + 0.5).abs() < 1e-2,
                "{t}: {s}"
            );
        }
        assert!(smooth(&times, &vec![None; times.len()], 1.0).is_none());
    }
}
