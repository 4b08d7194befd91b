//! The labelled SMC-PHD filter's state and steps a–f ([`LabelledPhd`]), and the k-means of
//! step a) and the split rule.

use super::super::resample::resample;
use super::super::{Particles, SurveillanceRegion};
use super::{BatchEval, LabelEstimate, LabelUpdate, PhdConfig};
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::rng::{Rng, Stream, rng_for};
use rand::RngExt as _;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// The labelled SMC-PHD filter's state: particles (struct of arrays), labels and streams.
#[derive(Debug, Clone)]
pub struct LabelledPhd {
    config: PhdConfig,
    region: SurveillanceRegion,
    pub(super) particles: Particles,
    pub(super) next_label: u32,
    seed: u64,
    step: u64,
    dt: f64,
    rng: Rng,
    scratch: Vec<usize>,
}

impl LabelledPhd {
    /// An empty filter over `region` (the state and observation space).
    ///
    /// # Errors
    /// When the config or the region is invalid.
    pub fn new(config: PhdConfig, region: SurveillanceRegion, seed: u64) -> Result<Self> {
        config.validate()?;
        if !region.is_valid() {
            return Err(Error::Invalid(format!(
                "PHD filter: region {region:?} must have positive, finite size"
            )));
        }
        Ok(Self {
            config,
            region,
            particles: Particles::default(),
            next_label: 1,
            seed,
            step: 0,
            dt: 1.0,
            rng: rng_for(seed, Stream::Phd, u64::MAX),
            scratch: Vec::new(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &PhdConfig {
        &self.config
    }

    /// The region.
    pub fn region(&self) -> SurveillanceRegion {
        self.region
    }

    /// The particles.
    pub fn particles(&self) -> &Particles {
        &self.particles
    }

    /// Mutable particles (for the likelihood pass: write `h`).
    pub fn particles_mut(&mut self) -> &mut Particles {
        &mut self.particles
    }

    /// The expected number of objects: the sum of weights.
    pub fn expected_count(&self) -> f64 {
        self.particles.total_weight()
    }

    pub(super) fn new_label(&mut self) -> u32 {
        let l = self.next_label;
        self.next_label += 1;
        l
    }

    pub(super) fn gaussian(&mut self) -> f64 {
        StandardNormal.sample(&mut self.rng)
    }

    /// Places `ρ` particles around each `(position, velocity)` with a fresh label each,
    /// total weight 1 per object (an initial distribution from detections).
    pub fn initialise_at(&mut self, objects: &[(Point, Point)], spread: f64) {
        let rho = self.config.particles_per_object;
        for &(p, v) in objects {
            let label = self.new_label();
            for _ in 0..rho {
                let pos = Point::new(
                    p.x + spread * self.gaussian(),
                    p.y + spread * self.gaussian(),
                );
                let s = self.config.birth_speed_sigma * 0.25;
                let vel = Point::new(v.x + s * self.gaussian(), v.y + s * self.gaussian());
                self.particles.push(pos, vel, 1.0 / rho as f64, label);
            }
        }
    }

    /// Step a): `ρ·n` particles uniform over the region with birth velocities, weighted by
    /// `h` (from `eval`), resampled to `ρ·n` with total weight `n`, and labelled by k-means
    /// with `n` clusters.
    ///
    /// # Errors
    /// When `eval` fails.
    pub fn initialise_uniform(&mut self, n_objects: usize, eval: &mut BatchEval<'_>) -> Result<()> {
        if n_objects == 0 {
            return Ok(());
        }
        let n = self.config.particles_per_object * n_objects;
        let start = self.particles.len();
        for _ in 0..n {
            let pos = Point::new(
                self.region.x0 + self.region.width() * self.rng.random::<f64>(),
                self.region.y0 + self.region.height() * self.rng.random::<f64>(),
            );
            let s = self.config.birth_speed_sigma;
            let vel = Point::new(s * self.gaussian(), s * self.gaussian());
            self.particles.push(pos, vel, 1.0, 0);
        }
        let positions: Vec<Point> = (start..start + n).map(|i| self.particles.pos(i)).collect();
        let mut h = vec![0.0; n];
        eval(&positions, &mut h)?;
        let mut fresh = Particles::with_capacity(n);
        for i in start..start + n {
            fresh.push(
                self.particles.pos(i),
                Point::new(self.particles.vx[i], self.particles.vy[i]),
                h[i - start],
                0,
            );
            fresh.h[i - start] = h[i - start];
        }
        self.particles.x.truncate(start);
        self.particles.y.truncate(start);
        self.particles.vx.truncate(start);
        self.particles.vy.truncate(start);
        self.particles.w.truncate(start);
        self.particles.label.truncate(start);
        self.particles.h.truncate(start);
        resample(
            self.config.resampling,
            &fresh.w,
            n,
            &mut self.rng,
            &mut self.scratch,
        );
        if self.scratch.is_empty() {
            // Every h is 0: keep the uniform spread.
            self.scratch.extend(0..n);
        }
        let ancestors = std::mem::take(&mut self.scratch);
        fresh.select(&ancestors, n_objects as f64 / n as f64);
        self.scratch = ancestors;
        let pts: Vec<Point> = (0..fresh.len()).map(|i| fresh.pos(i)).collect();
        let assign = kmeans(&pts, &fresh.w, n_objects);
        let labels: Vec<u32> = (0..n_objects).map(|_| self.new_label()).collect();
        for (i, a) in assign.iter().enumerate() {
            fresh.label[i] = labels[*a];
        }
        for i in 0..fresh.len() {
            self.particles.push(
                fresh.pos(i),
                Point::new(fresh.vx[i], fresh.vy[i]),
                fresh.w[i],
                fresh.label[i],
            );
            let last = self.particles.len() - 1;
            self.particles.h[last] = fresh.h[i];
        }
        Ok(())
    }

    /// Step b): `w̃ = p_s·w` and propagation by the system model over `dt`.
    pub fn predict(&mut self, dt: f64) {
        self.step += 1;
        self.dt = dt;
        let ps = self.config.survival_prob;
        self.particles.w.iter_mut().for_each(|w| *w *= ps);
        let p = &mut self.particles;
        self.config.motion.propagate(
            &mut p.x,
            &mut p.y,
            &mut p.vx,
            &mut p.vy,
            dt,
            self.seed,
            Stream::Phd,
            self.step,
        );
    }

    /// Step c), the paper's form: `μ_Γ` spread over a fixed grid of
    /// [`PhdConfig::birth_grid_points`] points covering the region, each with weight
    /// `μ_Γ / n` and a velocity drawn from the birth prior; unlabelled.
    pub fn add_grid_births(&mut self) {
        let n = self.config.birth_grid_points;
        if n == 0 || self.config.birth_rate <= 0.0 {
            return;
        }
        let (cols, rows) = grid_shape(n, self.region.width(), self.region.height());
        let w = self.config.birth_rate / (cols * rows) as f64;
        let s = self.config.birth_speed_sigma;
        for r in 0..rows {
            for c in 0..cols {
                let pos = Point::new(
                    self.region.x0 + self.region.width() * (c as f64 + 0.5) / cols as f64,
                    self.region.y0 + self.region.height() * (r as f64 + 0.5) / rows as f64,
                );
                let vel = Point::new(s * self.gaussian(), s * self.gaussian());
                self.particles.push(pos, vel, w, 0);
            }
        }
    }

    /// `per_point` birth particles for each of `n_points` points, fewer when that would add
    /// more than [`PhdConfig::max_particles`] particles in one step.
    // Choice: the cap on particles also caps one step's births (at least one particle per
    // point), so a large `birth_particles_per_detection` or a crowded frame cannot grow
    // the set without bound before resampling; the particle count stays below twice
    // `max_particles` plus one per point. Below the cap nothing changes.
    pub(super) fn births_per_point(&self, per_point: usize, n_points: usize) -> usize {
        let max = self.config.max_particles;
        if n_points.saturating_mul(per_point) <= max {
            per_point
        } else {
            (max / n_points.max(1)).max(1)
        }
    }

    /// Step c), measurement-driven (Ristic, Clark & Vo 2010, the paper's ref. 10): `per_point`
    /// birth particles drawn around each of `points` (Gaussian, standard deviation
    /// `spread`), velocities from the birth prior, importance-weighted so that the birth
    /// intensity stays `μ_Γ` uniform over the region. Without points, births are uniform.
    ///
    /// Births proposed around the previous step's measurements are then moved by the
    /// system model over `advance_dt` (0 leaves them in place), so they meet the current
    /// step's measurements.
    pub fn add_measurement_births(
        &mut self,
        points: &[Point],
        per_point: usize,
        spread: f64,
        advance_dt: f64,
    ) {
        let mu = self.config.birth_rate;
        if mu <= 0.0 || per_point == 0 {
            return;
        }
        let per_point = self.births_per_point(per_point, points.len());
        let s = self.config.birth_speed_sigma;
        let area = self.region.area();
        if points.is_empty() || spread <= 0.0 {
            let n = self
                .config
                .birth_grid_points
                .max(per_point)
                .min(self.config.max_particles);
            for _ in 0..n {
                let pos = Point::new(
                    self.region.x0 + self.region.width() * self.rng.random::<f64>(),
                    self.region.y0 + self.region.height() * self.rng.random::<f64>(),
                );
                let vel = Point::new(s * self.gaussian(), s * self.gaussian());
                self.particles.push(pos, vel, mu / n as f64, 0);
            }
            return;
        }
        let total = points.len() * per_point;
        let norm = 1.0 / (2.0 * std::f64::consts::PI * spread * spread);
        for &z in points {
            for _ in 0..per_point {
                let pos = Point::new(
                    z.x + spread * self.gaussian(),
                    z.y + spread * self.gaussian(),
                );
                if !self.region.contains(pos) {
                    continue;
                }
                // Proposal density q(x) = (1/M) Σ_j N(x; z_j, spread²); target γ = μ_Γ / A.
                let q: f64 = points
                    .iter()
                    .map(|zj| {
                        let d2 = (pos.x - zj.x).powi(2) + (pos.y - zj.y).powi(2);
                        norm * (-0.5 * d2 / (spread * spread)).exp()
                    })
                    .sum::<f64>()
                    / points.len() as f64;
                let w = (mu / area) / (total as f64 * q);
                let mut st = [pos.x, pos.y, s * self.gaussian(), s * self.gaussian()];
                if advance_dt > 0.0 {
                    self.config
                        .motion
                        .propagate_one(&mut st, advance_dt, &mut self.rng);
                }
                self.particles
                    .push(Point::new(st[0], st[1]), Point::new(st[2], st[3]), w, 0);
            }
        }
    }

    /// Step c) from detections: `per_point` unlabelled birth particles around each of
    /// `points` (Gaussian, standard deviation `spread`), velocities from the birth prior;
    /// each point carries weight `min(1, μ_Γ / M)` for `M` points.
    // Choice: the birth intensity μ_Γ is spread over the detections the caller did not
    // explain by an existing label (Ristic, Clark & Vo 2010, adaptive births, without the
    // uniform importance correction of `add_measurement_births`), at most one object per
    // detection. The paper's classifier is also its detector; with a foreground detector
    // this puts births where objects appear instead of on a fixed grid.
    pub fn add_births_at(&mut self, points: &[Point], per_point: usize, spread: f64) {
        let mu = self.config.birth_rate;
        if points.is_empty() || per_point == 0 || mu <= 0.0 {
            return;
        }
        let per_point = self.births_per_point(per_point, points.len());
        let w = (mu / points.len() as f64).min(1.0) / per_point as f64;
        let s = self.config.birth_speed_sigma;
        for &z in points {
            for _ in 0..per_point {
                let pos = Point::new(
                    z.x + spread * self.gaussian(),
                    z.y + spread * self.gaussian(),
                );
                let vel = Point::new(s * self.gaussian(), s * self.gaussian());
                self.particles.push(pos, vel, w, 0);
            }
        }
    }

    /// Estimates of every label with positive weight, reported or not, sorted by label.
    pub fn all_estimates(&self) -> Vec<LabelEstimate> {
        self.label_members()
            .into_iter()
            .filter_map(|(label, idx)| {
                let (pos, vel, weight) = self.particles.weighted_mean(idx.into_iter())?;
                Some(LabelEstimate {
                    label,
                    pos,
                    vel,
                    weight,
                })
            })
            .collect()
    }

    /// Removes every particle of `labels` (their weight leaves the expected count).
    pub fn remove_labels(&mut self, labels: &[u32]) {
        if labels.is_empty() {
            return;
        }
        let keep: Vec<usize> = (0..self.particles.len())
            .filter(|&i| !labels.contains(&self.particles.label[i]))
            .collect();
        let w: Vec<f64> = keep.iter().map(|&i| self.particles.w[i]).collect();
        self.particles.select(&keep, 0.0);
        self.particles.w = w;
    }

    /// Step d) on images, eqs. 11–13 with `C(y)` per label (METHODS.md §3 d):
    ///
    /// ```text
    /// C_ℓ   = Σ_{i∈ℓ} w̃_i · h_i                          (eq. 13, one observation per label ℓ)
    /// ŵ_i  = [(1 − p_D) + p_D · h_i / (κ + C_ℓ(i))] · w̃_i   (eqs. 11, 12)
    /// ```
    ///
    /// `h` must already be in [`Particles::h`]. An unlabelled particle's observation is its
    /// mesh cell, with `C` summed over every particle in the cell, labelled or not. With
    /// [`LabelUpdate::Bernoulli`] labelled particles are updated as one Bernoulli component
    /// per label with the likelihood ratio `f_i = (1 − p_D) + p_D·h_i/κ`
    /// (`bernoulli_labels`).
    // Choice: the paper computes C(y) "per label" but does not say what observation an
    // unlabelled (birth) particle belongs to. Taking each alone gives every birth particle
    // on an object a whole object's weight; taking all unlabelled particles together lets
    // the background births add up to an object. The mesh cell (the unit of the
    // label-birth rule) with C over all its particles makes unlabelled particles next to a
    // tracked object share that object's observation with its label (as the standard PHD
    // normaliser does), so they do not add a phantom object per cell.
    pub fn update_image(&mut self) {
        let p = &self.particles;
        let cells: Vec<i64> = (0..p.len())
            .map(|i| self.mesh_key(p.x[i], p.y[i]))
            .collect();
        let mut c_label: BTreeMap<u32, f64> = BTreeMap::new();
        let mut c_cell: BTreeMap<i64, f64> = BTreeMap::new();
        for (i, cell) in cells.iter().enumerate() {
            let wh = p.w[i] * p.h[i];
            *c_cell.entry(*cell).or_insert(0.0) += wh;
            if p.label[i] != 0 {
                *c_label.entry(p.label[i]).or_insert(0.0) += wh;
            }
        }
        let (pd, kappa) = (self.config.detection_prob, self.config.clutter_intensity);
        let bernoulli = self.config.label_update == LabelUpdate::Bernoulli;
        let mut factor = Vec::new();
        let p = &mut self.particles;
        for (i, cell) in cells.iter().enumerate() {
            if bernoulli && p.label[i] != 0 {
                // The label's own observation: clutter κ is the only alternative.
                factor.push((1.0 - pd) + pd * p.h[i] / kappa);
                continue;
            }
            factor.push(0.0);
            let c = if p.label[i] == 0 {
                c_cell.get(cell)
            } else {
                c_label.get(&p.label[i])
            }
            .copied()
            .unwrap_or(0.0);
            let psi = p.h[i] / (kappa + c);
            p.w[i] *= (1.0 - pd) + pd * psi;
        }
        if bernoulli {
            self.bernoulli_labels(&factor);
        }
    }

    /// [`LabelUpdate::Bernoulli`]: each label `ℓ` is a Bernoulli component with existence
    /// `r = min(W̃_ℓ, 1)`; with `f_i` the particle's likelihood ratio against clutter
    /// (`factor`, read for labelled particles only), `1 − Δ = Σ_{i∈ℓ} w̃_i f_i / W̃_ℓ`,
    /// `r' = r(1 − Δ)/(1 − r + r(1 − Δ))` and `ŵ_i = w̃_i f_i · r' / Σ_{i∈ℓ} w̃_i f_i`
    /// (the Bernoulli filter's update; Ristic, Vo, Vo & Farina, "A tutorial on Bernoulli
    /// filters", Proc. IEEE 2013).
    pub(super) fn bernoulli_labels(&mut self, factor: &[f64]) {
        let p = &mut self.particles;
        // label → (W̃, Σ w̃ f), in particle order (deterministic).
        let mut sums: BTreeMap<u32, (f64, f64)> = BTreeMap::new();
        for ((&l, &w), &f) in p.label.iter().zip(&p.w).zip(factor) {
            if l != 0 {
                let e = sums.entry(l).or_insert((0.0, 0.0));
                e.0 += w;
                e.1 += w * f;
            }
        }
        let scale: BTreeMap<u32, f64> = sums
            .into_iter()
            .map(|(l, (w, s))| {
                if !(w > 0.0 && s > 0.0 && s.is_finite()) {
                    return (l, 0.0);
                }
                let r = w.min(1.0);
                let ratio = s / w;
                let r_post = r * ratio / (1.0 - r + r * ratio);
                (l, r_post / s)
            })
            .collect();
        for ((w, l), &f) in p.w.iter_mut().zip(&p.label).zip(factor) {
            if let Some(k) = scale.get(l) {
                *w *= f * k;
            }
        }
    }

    fn mesh_key(&self, x: f64, y: f64) -> i64 {
        let cell = self.config.mesh_cell;
        let cx = ((x - self.region.x0) / cell).floor().clamp(-1e6, 1e6) as i64;
        let cy = ((y - self.region.y0) / cell).floor().clamp(-1e6, 1e6) as i64;
        cx * 2_000_003 + cy
    }

    /// Step d) on point measurements `z` with a Gaussian likelihood of standard deviation
    /// `sigma` (the standard SMC-PHD update of Vo, Singh & Doucet 2003):
    ///
    /// ```text
    /// g_ij = p_D · N(z_j; x_i, σ²I)
    /// C_j  = Σ_i g_ij · w̃_i
    /// ŵ_i = [(1 − p_D) + Σ_j g_ij / (κ + C_j)] · w̃_i
    /// ```
    ///
    /// with `κ = clutter_rate / area`. `h_i = max_j exp(−|z_j − x_i|²/(2σ²))` is stored for
    /// the label rules. With [`LabelUpdate::Bernoulli`] labelled particles are updated as
    /// one Bernoulli component per label with `f_i = (1 − p_D) + Σ_j g_ij/(κ + C_j − C_ℓ,j)`
    /// (`bernoulli_labels`); unlabelled ones as above.
    // Choice: point measurements are genuine observations, so C(z) sums over all particles
    // and carries p_D (Vo et al. 2003, the paper's ref. 9), which makes one detected object
    // contribute one unit of weight; METHODS.md's per-label C without p_D is the image form.
    pub fn update_points(&mut self, z: &[Point], sigma: f64, clutter_rate: f64) {
        let pd = self.config.detection_prob;
        let kappa = clutter_rate / self.region.area();
        let p = &mut self.particles;
        let n = p.len();
        let m = z.len();
        let norm = pd / (2.0 * std::f64::consts::PI * sigma * sigma);
        let inv2s2 = 0.5 / (sigma * sigma);
        let e = |i: usize, zj: &Point| {
            (-((p.x[i] - zj.x).powi(2) + (p.y[i] - zj.y).powi(2)) * inv2s2).exp()
        };
        if m == 0 {
            p.h.iter_mut().for_each(|h| *h = 0.0);
        }
        // g is n × m; it is computed a block of rows at a time (in parallel) and computed
        // again for ψ instead of being kept whole, so memory stays `ROWS × m` however many
        // particles and measurements there are (n × m reached 8 GB). The sums run in the
        // same order as with the whole matrix, so the result is bit-identical.
        const ROWS: usize = 4096;
        let mut c = vec![0.0; m];
        let mut g = vec![0.0; ROWS.min(n) * m];
        if m > 0 {
            for start in (0..n).step_by(ROWS) {
                let rows = ROWS.min(n - start);
                let block = &mut g[..rows * m];
                block
                    .par_chunks_mut(m)
                    .zip(p.h[start..start + rows].par_iter_mut())
                    .enumerate()
                    .for_each(|(k, (row, h))| {
                        let mut best = 0.0f64;
                        for (j, zj) in z.iter().enumerate() {
                            let ej = e(start + k, zj);
                            row[j] = norm * ej;
                            best = best.max(ej);
                        }
                        *h = best;
                    });
                for k in 0..rows {
                    let w = p.w[start + k];
                    for j in 0..m {
                        c[j] += block[k * m + j] * w;
                    }
                }
            }
        }
        drop(g);
        // One entry of g, computed again (bit-identical to the block above).
        let g_at = |i: usize, j: usize| norm * e(i, &z[j]);
        if self.config.label_update == LabelUpdate::Phd {
            let psi: Vec<f64> = (0..n)
                .into_par_iter()
                .map(|i| (0..m).map(|j| g_at(i, j) / (kappa + c[j])).sum())
                .collect();
            for (w, psi) in p.w.iter_mut().zip(psi) {
                *w *= (1.0 - pd) + psi;
            }
            return;
        }
        // Bernoulli labels: C_ℓ(z_j) per label; a label's alternative explanation of z_j
        // is clutter plus every other particle, κ + C(z_j) − C_ℓ(z_j).
        let mut slot: BTreeMap<u32, usize> = BTreeMap::new();
        for &l in &p.label {
            if l != 0 {
                let next = slot.len();
                slot.entry(l).or_insert(next);
            }
        }
        let mut c_label = vec![0.0; slot.len() * m];
        for i in 0..n {
            if let Some(&s) = slot.get(&p.label[i]) {
                for j in 0..m {
                    c_label[s * m + j] += g_at(i, j) * p.w[i];
                }
            }
        }
        let mut factor = vec![0.0; n];
        for (i, f) in factor.iter_mut().enumerate() {
            match slot.get(&p.label[i]) {
                None => {
                    let psi: f64 = (0..m).map(|j| g_at(i, j) / (kappa + c[j])).sum();
                    p.w[i] *= (1.0 - pd) + psi;
                }
                Some(&s) => {
                    let own = &c_label[s * m..(s + 1) * m];
                    *f = (1.0 - pd)
                        + (0..m)
                            .map(|j| g_at(i, j) / (kappa + (c[j] - own[j]).max(0.0)))
                            .sum::<f64>();
                }
            }
        }
        self.bernoulli_labels(&factor);
    }

    /// Step e): the label rules in the paper's order.
    ///
    /// 1. `h < β_likelihood` → label 0 (unless the whole label is unsupported and
    ///    [`PhdConfig::keep_unsupported_labels`] is set);
    /// 2. a label within `β_position` of the border moving outward faster than `α_speed`
    ///    ends (label 0);
    /// 3. each label is split in two by weighted 2-means; if the centres are more than
    ///    `α_spawned` apart, the lighter cluster gets a new label;
    /// 4. unlabelled particles of a mesh cell whose mean `h` exceeds `α_mesh` get a new label;
    /// 5. labels whose centres are closer than `β_center` merge into the oldest.
    pub fn update_labels(&mut self) {
        self.rule_likelihood();
        self.rule_border_exit();
        self.rule_split();
        self.rule_mesh_birth();
        self.rule_merge();
    }

    fn label_members(&self) -> BTreeMap<u32, Vec<usize>> {
        let mut m: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
        for (i, &l) in self.particles.label.iter().enumerate() {
            if l != 0 {
                m.entry(l).or_default().push(i);
            }
        }
        m
    }

    pub(super) fn rule_likelihood(&mut self) {
        let beta = self.config.likelihood_threshold;
        let keep: Vec<u32> = if self.config.keep_unsupported_labels {
            self.label_members()
                .into_iter()
                .filter(|(_, idx)| idx.iter().all(|&i| self.particles.h[i] < beta))
                .map(|(l, _)| l)
                .collect()
        } else {
            Vec::new()
        };
        let p = &mut self.particles;
        for i in 0..p.len() {
            if p.label[i] != 0 && p.h[i] < beta && !keep.contains(&p.label[i]) {
                p.label[i] = 0;
            }
        }
    }

    pub(super) fn rule_border_exit(&mut self) {
        let (margin, speed) = (self.config.border_margin, self.config.exit_speed);
        if !speed.is_finite() {
            return;
        }
        let r = self.region;
        let dt = self.dt;
        for (_, idx) in self.label_members() {
            let Some((c, v, _)) = self.particles.weighted_mean(idx.iter().copied()) else {
                continue;
            };
            let (dx, dy) = (v.x * dt, v.y * dt);
            // Choice: the rule is applied to the label's weighted mean (METHODS.md: "a label
            // … ends"), not particle by particle, so a label never half-exits.
            let exits = (c.x - r.x0 <= margin && -dx > speed)
                || (r.x1 - c.x <= margin && dx > speed)
                || (c.y - r.y0 <= margin && -dy > speed)
                || (r.y1 - c.y <= margin && dy > speed);
            if exits {
                for &i in &idx {
                    self.particles.label[i] = 0;
                }
            }
        }
    }

    fn rule_split(&mut self) {
        let alpha = self.config.split_distance;
        for (_, idx) in self.label_members() {
            if idx.len() < 2 {
                continue;
            }
            let pts: Vec<Point> = idx.iter().map(|&i| self.particles.pos(i)).collect();
            let ws: Vec<f64> = idx.iter().map(|&i| self.particles.w[i]).collect();
            let assign = kmeans(&pts, &ws, 2);
            let mut cw = [0.0f64; 2];
            let mut cx = [0.0f64; 2];
            let mut cy = [0.0f64; 2];
            for (k, &a) in assign.iter().enumerate() {
                cw[a] += ws[k];
                cx[a] += ws[k] * pts[k].x;
                cy[a] += ws[k] * pts[k].y;
            }
            if cw[0] <= 0.0 || cw[1] <= 0.0 {
                continue;
            }
            let d = (cx[0] / cw[0] - cx[1] / cw[1]).hypot(cy[0] / cw[0] - cy[1] / cw[1]);
            if d > alpha {
                // Choice: the heavier cluster keeps the label (identity follows the mass).
                let light = usize::from(cw[1] <= cw[0]);
                let label = self.new_label();
                for (k, &a) in assign.iter().enumerate() {
                    if a == light {
                        self.particles.label[idx[k]] = label;
                    }
                }
            }
        }
    }

    pub(super) fn rule_mesh_birth(&mut self) {
        let alpha = self.config.mesh_likelihood_threshold;
        let mut cells: BTreeMap<i64, (f64, Vec<usize>)> = BTreeMap::new();
        for i in 0..self.particles.len() {
            if self.particles.label[i] == 0 {
                let e = cells
                    .entry(self.mesh_key(self.particles.x[i], self.particles.y[i]))
                    .or_insert((0.0, Vec::new()));
                e.0 += self.particles.h[i];
                e.1.push(i);
            }
        }
        for (_, (sum_h, idx)) in cells {
            if sum_h / idx.len() as f64 > alpha {
                let label = self.new_label();
                for i in idx {
                    self.particles.label[i] = label;
                }
            }
        }
    }

    pub(super) fn rule_merge(&mut self) {
        let beta = self.config.merge_distance;
        let centres: Vec<(u32, Point)> = self
            .label_members()
            .into_iter()
            .filter_map(|(l, idx)| {
                self.particles
                    .weighted_mean(idx.into_iter())
                    .map(|(c, _, _)| (l, c))
            })
            .collect();
        // Union into the smallest (oldest) label; centres are those before merging.
        let mut target: BTreeMap<u32, u32> = BTreeMap::new();
        for a in 0..centres.len() {
            for b in a + 1..centres.len() {
                if centres[a].1.distance(centres[b].1) < beta {
                    let root_a = resolve(&target, centres[a].0);
                    let root_b = resolve(&target, centres[b].0);
                    if root_a != root_b {
                        target.insert(root_a.max(root_b), root_a.min(root_b));
                    }
                }
            }
        }
        if target.is_empty() {
            return;
        }
        for l in self.particles.label.iter_mut() {
            if *l != 0 {
                *l = resolve(&target, *l);
            }
        }
    }

    /// Per-label estimates (weighted means), sorted by label, of every label whose weight
    /// reaches [`PhdConfig::report_weight`].
    pub fn estimates(&self) -> Vec<LabelEstimate> {
        self.label_members()
            .into_iter()
            .filter_map(|(label, idx)| {
                let (pos, vel, weight) = self.particles.weighted_mean(idx.into_iter())?;
                (weight >= self.config.report_weight).then_some(LabelEstimate {
                    label,
                    pos,
                    vel,
                    weight,
                })
            })
            .collect()
    }

    /// Step f): stratified (or systematic) resampling, label by label. Label `ℓ` with
    /// weight `W_ℓ` gets `max(⌈ρ·W_ℓ⌉, ρ)` particles of weight `W_ℓ/n` (so every label keeps
    /// its weight and the expected count is unchanged); unlabelled particles get `⌈ρ·W₀⌉`.
    /// Labels lighter than [`PhdConfig::prune_weight`] and particles outside the region are
    /// dropped first.
    // Choice: the paper resamples all particles together. Then a hypothesis of small weight
    // (a new object at its first update has ~μ_Γ/(clutter + μ_Γ) ≪ 1) keeps one or two
    // particles and cannot find its velocity, so new objects are never confirmed; per-label
    // resampling with a floor of ρ (as in labelled / partitioned SMC-PHD filters) fixes this
    // without changing any weight. Particles that left the region carry objects that left
    // the scene (the state space is the region).
    pub fn resample(&mut self) {
        let r = self.region;
        let rho = self.config.particles_per_object;
        let mut groups: BTreeMap<u32, (f64, Vec<usize>)> = BTreeMap::new();
        for i in 0..self.particles.len() {
            let w = self.particles.w[i];
            if r.contains(self.particles.pos(i)) && w.is_finite() && w > 0.0 {
                let g = groups
                    .entry(self.particles.label[i])
                    .or_insert((0.0, Vec::new()));
                g.0 += w;
                g.1.push(i);
            }
        }
        let mut plan: Vec<(f64, Vec<usize>, usize)> = groups
            .into_iter()
            .filter(|(l, (w, _))| *l == 0 || *w >= self.config.prune_weight)
            .map(|(l, (w, idx))| {
                let n = (rho as f64 * w).ceil() as usize;
                let n = if l == 0 { n } else { n.max(rho) };
                (w, idx, n)
            })
            .filter(|(_, _, n)| *n > 0)
            .collect();
        let total_n: usize = plan.iter().map(|p| p.2).sum();
        if total_n > self.config.max_particles {
            let scale = self.config.max_particles as f64 / total_n as f64;
            for p in &mut plan {
                p.2 = ((p.2 as f64 * scale).floor() as usize).max(1);
            }
        }
        let mut ancestors = Vec::with_capacity(plan.iter().map(|p| p.2).sum());
        let mut weights = Vec::with_capacity(ancestors.capacity());
        let mut local = std::mem::take(&mut self.scratch);
        let mut w_group = Vec::new();
        for (w, idx, n) in &plan {
            w_group.clear();
            w_group.extend(idx.iter().map(|&i| self.particles.w[i]));
            resample(
                self.config.resampling,
                &w_group,
                *n,
                &mut self.rng,
                &mut local,
            );
            ancestors.extend(local.iter().map(|&k| idx[k]));
            weights.extend(std::iter::repeat_n(w / *n as f64, local.len()));
        }
        self.scratch = local;
        self.particles.select(&ancestors, 0.0);
        self.particles.w = weights;
        if self.config.roughening > 0.0 {
            self.roughen();
        }
    }

    /// Roughening (see [`PhdConfig::roughening`]), label by label; particles are grouped
    /// contiguously by label after [`LabelledPhd::resample`].
    fn roughen(&mut self) {
        let k = self.config.roughening;
        let n = self.particles.len();
        let mut start = 0;
        while start < n {
            let label = self.particles.label[start];
            let mut end = start;
            while end < n && self.particles.label[end] == label {
                end += 1;
            }
            let scale = k * ((end - start) as f64).powf(-0.25);
            let p = &mut self.particles;
            for comp in [&mut p.x, &mut p.y, &mut p.vx, &mut p.vy] {
                let s = &mut comp[start..end];
                let (lo, hi) = s
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                let sigma = scale * (hi - lo);
                if sigma > 0.0 && sigma.is_finite() {
                    for v in s.iter_mut() {
                        let z: f64 = StandardNormal.sample(&mut self.rng);
                        *v += sigma * z;
                    }
                }
            }
            start = end;
        }
    }
}

/// The root of `l` in the merge map.
fn resolve(map: &BTreeMap<u32, u32>, mut l: u32) -> u32 {
    while let Some(&t) = map.get(&l) {
        l = t;
    }
    l
}

/// The grid `cols × rows ≈ n` with cells as square as the region allows.
fn grid_shape(n: usize, width: f64, height: f64) -> (usize, usize) {
    let cols = ((n as f64 * width / height).sqrt().round() as usize).clamp(1, n);
    let rows = n.div_ceil(cols).max(1);
    (cols, rows)
}

/// Weighted k-means on positions with deterministic farthest-point initialisation
/// (first centre: the point farthest from the weighted mean). Returns each point's cluster.
pub(super) fn kmeans(points: &[Point], weights: &[f64], k: usize) -> Vec<usize> {
    let n = points.len();
    if n == 0 || k <= 1 {
        return vec![0; n];
    }
    let k = k.min(n);
    let sw: f64 = weights.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let mean = Point::new(
        points
            .iter()
            .zip(weights)
            .map(|(p, w)| p.x * w)
            .sum::<f64>()
            / sw,
        points
            .iter()
            .zip(weights)
            .map(|(p, w)| p.y * w)
            .sum::<f64>()
            / sw,
    );
    let farthest = |from: &dyn Fn(Point) -> f64| {
        let mut best = (0, f64::NEG_INFINITY);
        for (i, &p) in points.iter().enumerate() {
            let d = from(p);
            if d > best.1 {
                best = (i, d);
            }
        }
        best.0
    };
    let mut centres = vec![points[farthest(&|p| p.distance(mean))]];
    while centres.len() < k {
        let c = centres.clone();
        let i = farthest(&|p| {
            c.iter()
                .map(|q| p.distance(*q))
                .fold(f64::INFINITY, f64::min)
        });
        centres.push(points[i]);
    }
    let mut assign = vec![0; n];
    for _ in 0..50 {
        let mut changed = false;
        for (i, &p) in points.iter().enumerate() {
            let mut best = (0, f64::INFINITY);
            for (j, &c) in centres.iter().enumerate() {
                let d = p.distance(c);
                if d < best.1 {
                    best = (j, d);
                }
            }
            if assign[i] != best.0 {
                assign[i] = best.0;
                changed = true;
            }
        }
        let mut acc = vec![(0.0, 0.0, 0.0); k];
        for (i, &p) in points.iter().enumerate() {
            let w = weights[i].max(0.0);
            let a = &mut acc[assign[i]];
            a.0 += w;
            a.1 += w * p.x;
            a.2 += w * p.y;
        }
        for (j, a) in acc.iter().enumerate() {
            if a.0 > 0.0 {
                centres[j] = Point::new(a.1 / a.0, a.2 / a.0);
            }
        }
        if !changed {
            break;
        }
    }
    assign
}
