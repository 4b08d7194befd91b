//! Steps 3–5 of METHODS.md §2: the Gibbs sampler (stochastic relaxation, Geman & Geman)
//! over the (id, motion vector) state of every contested block, double-buffered.
//!
//! One sweep computes, for every site, the energy (eq. 5) of each (candidate id, proposed
//! vector) pair from the *current* maps only, draws the next state with probability
//! `∝ exp(−U / T)`, and only then writes all new states at once, so a change never
//! propagates within a sweep (the paper's requirement in §3.5).

use super::energy::{
    Terms, neighbour_count, overlap_pixels, smoothness_energy, texture_sad, total_energy,
};
use super::object_map::{BlockGrid, ObjectId, ObjectMap, Vector};
use super::propagate::{Candidate, GibbsSite};
use super::{MrfConfig, MrfVariant};
use crate::rng::{Stream, rng_for};
use image::GrayImage;
use rand::RngExt as _;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// What the sampler reads and never changes.
#[derive(Debug, Clone, Copy)]
pub struct Context<'a> {
    /// Luminance of frame `t − 1`.
    pub prev_gray: &'a GrayImage,
    /// Luminance of frame `t`.
    pub cur_gray: &'a GrayImage,
    /// `X(t − 1)`.
    pub prev_map: &'a ObjectMap,
    /// Parameters (weights, variant, temperature, stop rule).
    pub config: &'a MrfConfig,
    /// Representative vector of each object: the most frequent vector over its `t − 1`
    /// blocks (legacy: the vector of `M` and `D`; improved: the centre of the proposals).
    pub representative: &'a BTreeMap<ObjectId, Vector>,
    /// Run seed.
    pub seed: u64,
    /// Frame number `t` (keys the random streams).
    pub frame: u32,
}

/// Summary of one optimisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GibbsStats {
    /// Sweeps run.
    pub iterations: u32,
    /// Blocks whose id changed in the last sweep.
    pub id_changes: u32,
    /// Blocks whose vector changed by more than `v_diff_px` in the last sweep.
    pub vector_changes: u32,
    /// Whether the stop rule (rather than `max_iterations`) ended the loop.
    pub converged: bool,
}

/// Temperature of sweep `iteration` (0-based): `max(T0 · cooling^i, T_min)`.
// Choice: geometric cooling (paper silent on the schedule; METHODS.md §2 asks for one).
pub fn temperature(config: &MrfConfig, iteration: u32) -> f64 {
    (config.initial_temperature * config.cooling.powi(iteration as i32)).max(config.min_temperature)
}

/// The vectors the sampler may give a site together with candidate id `candidate`
/// (improved variant). `bound` is `(representative, tolerance_px)`: the candidate object's
/// representative vector (most frequent block-matching vector over its `t − 1` blocks) and
/// how far (per axis) a proposal may lie from it; the representative is always proposed
/// itself. `None` (object without a representative yet): no bound.
// Choice: the vector belongs to the candidate: D and M of candidate O_m use "the local
// vector of the O_m block it came from" (§3.2), so each candidate proposes its own vectors —
// its object's representative vector, its block-matching (local) vector, the current
// vectors of the 8 neighbours that carry the same id, and, when the site currently carries
// this id, its current vector and that vector ±1 px along each axis — deduplicated and kept
// within the search window. Not all 49 × 49 vectors (METHODS.md §2 suggests this set as
// sound and far cheaper); sharing one set between ids would let every id borrow the
// best-matching vector and make D blind to the id.
// Choice (tolerance): every proposal of O_m must lie within `local_vector_tolerance_px` of
// O_m's representative vector. Without this bound, a wrongly labelled edge block's local
// vector (and its neighbours' and ±1 px steps) follows the texture the block actually shows
// — the intruder's — so the wrong id explains that texture as well as the right one, D
// cannot correct the id, and M and N keep the status quo (measured: the side-by-side group
// lost a ≥ 10-block object in 14 of 46 object-frames; legacy, whose single representative
// vector keeps D discriminative, lost none). With the bound, a local vector may still differ
// from its object's motion (non-rigid motion, perspective) by the tolerance, but an object
// can no longer take another object's motion. Default 0 (each object's blocks are evaluated
// with its representative motion; the f term still weighs it against the neighbours');
// 48 (twice the window) switches the bound off.
pub fn proposals(
    site: &GibbsSite,
    candidate: &Candidate,
    grid: &BlockGrid,
    ids: &[ObjectId],
    vectors: &[Option<Vector>],
    radius_px: u32,
    bound: Option<(Vector, u32)>,
) -> Vec<Vector> {
    let mut out: Vec<Vector> = Vec::with_capacity(16);
    let r = radius_px as i16;
    let representative = bound.map(|(c, _)| c);
    let near = |v: Vector| {
        bound.is_none_or(|(c, tolerance_px)| {
            let tol = i64::from(tolerance_px);
            (i64::from(v[0]) - i64::from(c[0])).abs() <= tol
                && (i64::from(v[1]) - i64::from(c[1])).abs() <= tol
        })
    };
    let mut push = |v: Vector| {
        if v[0].abs() <= r && v[1].abs() <= r && near(v) && !out.contains(&v) {
            out.push(v);
        }
    };
    let current = (ids[site.block] == candidate.id)
        .then_some(vectors[site.block])
        .flatten();
    if let Some(v) = current {
        push(v);
    }
    if let Some(v) = representative {
        push(v);
    }
    push(candidate.vector);
    for nb in grid.neighbours8(site.block).into_iter().flatten() {
        if let (true, Some(v)) = (ids[nb] == candidate.id, vectors[nb]) {
            push(v);
        }
    }
    if let Some(v) = current {
        for d in [[1, 0], [-1, 0], [0, 1], [0, -1]] {
            push([v[0] + d[0], v[1] + d[1]]);
        }
    }
    if out.is_empty() {
        // The representative lies outside the window (cannot happen for block-matching
        // vectors): fall back to the candidate's own vector.
        out.push(candidate.vector);
    }
    out
}

/// Random key of (frame, sweep, block), so each draw has its own stream and the thread
/// count cannot change results.
fn draw_key(frame: u32, iteration: u32, block: usize) -> u64 {
    (u64::from(frame) << 40) ^ (u64::from(iteration) << 24) ^ block as u64
}

/// Energies of every (candidate, vector) state of `site` under the current maps, in the
/// order candidates × vectors (legacy: one vector per candidate, its object's
/// representative).
pub fn site_energies(
    ctx: &Context<'_>,
    site: &GibbsSite,
    ids: &[ObjectId],
    vectors: &[Option<Vector>],
) -> Vec<(ObjectId, Vector, f64)> {
    let grid = ctx.prev_map.grid;
    let cfg = ctx.config;
    let mut out = Vec::new();
    match cfg.variant {
        MrfVariant::Legacy => {
            for c in &site.candidates {
                let v = ctx.representative.get(&c.id).copied().unwrap_or(c.vector);
                let terms = Terms {
                    n: neighbour_count(ids, &grid, site.block, c.id),
                    m: overlap_pixels(ctx.prev_map, site.block, v, c.id),
                    d: texture_sad(ctx.prev_gray, ctx.cur_gray, &grid, site.block, v),
                    smoothness: 0.0,
                };
                out.push((c.id, v, total_energy(&terms, cfg)));
            }
        }
        MrfVariant::Improved => {
            for c in &site.candidates {
                let n = neighbour_count(ids, &grid, site.block, c.id);
                // Eq. 4 over every neighbour that carries a vector (the paper's U_mv does
                // not depend on the candidate id).
                let nbrs: Vec<Vector> = grid
                    .neighbours8(site.block)
                    .into_iter()
                    .flatten()
                    .filter_map(|nb| vectors[nb])
                    .collect();
                for v in proposals(
                    site,
                    c,
                    &grid,
                    ids,
                    vectors,
                    cfg.search_radius_px,
                    ctx.representative
                        .get(&c.id)
                        .map(|&r| (r, cfg.local_vector_tolerance_px)),
                ) {
                    let terms = Terms {
                        n,
                        m: overlap_pixels(ctx.prev_map, site.block, v, c.id),
                        d: texture_sad(ctx.prev_gray, ctx.cur_gray, &grid, site.block, v),
                        smoothness: smoothness_energy(v, nbrs.iter().copied(), cfg),
                    };
                    out.push((c.id, v, total_energy(&terms, cfg)));
                }
            }
        }
    }
    out
}

/// One double-buffered sweep: the next state of every site, computed from `ids` and
/// `vectors` only (nothing is written). Results are in the order of `sites`.
pub fn sweep(
    ctx: &Context<'_>,
    sites: &[GibbsSite],
    ids: &[ObjectId],
    vectors: &[Option<Vector>],
    iteration: u32,
) -> Vec<(ObjectId, Vector)> {
    let t = temperature(ctx.config, iteration);
    sites
        .par_iter()
        .with_min_len(8)
        .map(|site| {
            let states = site_energies(ctx, site, ids, vectors);
            let u_min = states.iter().map(|s| s.2).fold(f64::INFINITY, f64::min);
            let weights: Vec<f64> = states.iter().map(|s| (-(s.2 - u_min) / t).exp()).collect();
            let total: f64 = weights.iter().sum();
            let mut rng = rng_for(
                ctx.seed,
                Stream::Gibbs,
                draw_key(ctx.frame, iteration, site.block),
            );
            let mut u = rng.random::<f64>() * total;
            let mut chosen = states.len().saturating_sub(1);
            for (i, w) in weights.iter().enumerate() {
                if u < *w {
                    chosen = i;
                    break;
                }
                u -= w;
            }
            states
                .get(chosen)
                .map(|s| (s.0, s.1))
                .unwrap_or((ids[site.block], vectors[site.block].unwrap_or([0, 0])))
        })
        .collect()
}

/// Runs sweeps until the stop rule of Step 5 holds — fewer than `n_th_id` blocks changed id
/// and fewer than `n_th_mv` blocks changed vector by more than `v_diff_px` (`|Δv_x| + |Δv_y|`)
/// in the last sweep — or `max_iterations` sweeps ran. Updates `ids` and `vectors` in place
/// between sweeps (double buffer).
pub fn optimise(
    ctx: &Context<'_>,
    sites: &[GibbsSite],
    ids: &mut [ObjectId],
    vectors: &mut [Option<Vector>],
) -> GibbsStats {
    let cfg = ctx.config;
    let mut stats = GibbsStats::default();
    if sites.is_empty() {
        stats.converged = true;
        return stats;
    }
    for it in 0..cfg.max_iterations {
        let next = sweep(ctx, sites, ids, vectors, it);
        let (mut dn, mut dv) = (0u32, 0u32);
        for (site, (id, v)) in sites.iter().zip(next) {
            if ids[site.block] != id {
                dn += 1;
            }
            let old = vectors[site.block].unwrap_or(v);
            let l1 = (i32::from(old[0]) - i32::from(v[0])).abs()
                + (i32::from(old[1]) - i32::from(v[1])).abs();
            if l1 > cfg.v_diff_px as i32 {
                dv += 1;
            }
            ids[site.block] = id;
            vectors[site.block] = Some(v);
        }
        stats = GibbsStats {
            iterations: it + 1,
            id_changes: dn,
            vector_changes: dv,
            converged: dn < cfg.n_th_id && dv < cfg.n_th_mv,
        };
        if stats.converged {
            break;
        }
    }
    stats
}

/// The most frequent vector over each object's blocks (legacy variant's representative
/// vector); ties go to the smaller `(|v_x| + |v_y|, v_y, v_x)`.
pub fn representative_vectors(
    map: &ObjectMap,
    vectors: &[Option<Vector>],
) -> BTreeMap<ObjectId, Vector> {
    let mut counts: BTreeMap<ObjectId, BTreeMap<(i32, i16, i16), u32>> = BTreeMap::new();
    for (i, &id) in map.ids.iter().enumerate() {
        if id == super::object_map::NO_OBJECT {
            continue;
        }
        if let Some(v) = vectors.get(i).copied().flatten() {
            let key = (i32::from(v[0]).abs() + i32::from(v[1]).abs(), v[1], v[0]);
            *counts.entry(id).or_default().entry(key).or_insert(0) += 1;
        }
    }
    counts
        .into_iter()
        .filter_map(|(id, c)| {
            // max count; BTreeMap order makes the smallest key win ties (first max kept).
            let mut best: Option<((i32, i16, i16), u32)> = None;
            for (k, n) in c {
                if best.is_none_or(|(_, bn)| n > bn) {
                    best = Some((k, n));
                }
            }
            best.map(|((_, vy, vx), _)| (id, [vx, vy]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::rng_for;

    struct Scene {
        prev: GrayImage,
        cur: GrayImage,
        prev_map: ObjectMap,
    }

    /// Two textured objects: id 1 on the left half moving +4 px, id 2 on the right moving −4 px.
    fn scene() -> Scene {
        let (w, h) = (96u32, 64u32);
        let mut r = rng_for(1, Stream::Synthetic, 0);
        let tex: Vec<u8> = (0..w * h * 4).map(|_| r.random_range(0..255u8)).collect();
        let prev = GrayImage::from_fn(w, h, |x, y| image::Luma([tex[(y * w * 2 + x) as usize]]));
        let cur = GrayImage::from_fn(w, h, |x, y| {
            let sx = if x < 48 {
                x.saturating_sub(4)
            } else {
                (x + 4).min(w - 1)
            };
            image::Luma([tex[(y * w * 2 + sx) as usize]])
        });
        let grid = BlockGrid::for_frame(w, h);
        let mut prev_map = ObjectMap::empty(grid);
        for by in 1..7 {
            for bx in 1..11 {
                prev_map.ids[grid.index(bx, by)] = if bx < 6 { 1 } else { 2 };
            }
        }
        Scene {
            prev,
            cur,
            prev_map,
        }
    }

    fn contested(grid: &BlockGrid) -> Vec<GibbsSite> {
        (1..7)
            .flat_map(|by| [5u32, 6].map(|bx| (bx, by)))
            .map(|(bx, by)| GibbsSite {
                block: grid.index(bx, by),
                candidates: vec![
                    Candidate {
                        id: 1,
                        vector: [4, 0],
                        sad: 0,
                        rounded: true,
                    },
                    Candidate {
                        id: 2,
                        vector: [-4, 0],
                        sad: 0,
                        rounded: true,
                    },
                ],
            })
            .collect()
    }

    fn vectors_of(map: &ObjectMap) -> Vec<Option<Vector>> {
        map.ids
            .iter()
            .map(|&id| match id {
                1 => Some([4, 0]),
                2 => Some([-4, 0]),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn sampler_is_deterministic_for_a_seed_and_any_thread_count() -> crate::Result<()> {
        let s = scene();
        let cfg = MrfConfig::default();
        let rep = BTreeMap::new();
        let sites = contested(&s.prev_map.grid);
        let run =
            |seed: u64, threads: usize| -> crate::Result<(Vec<ObjectId>, Vec<Option<Vector>>)> {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .map_err(|e| crate::Error::Invalid(e.to_string()))?;
                let ctx = Context {
                    prev_gray: &s.prev,
                    cur_gray: &s.cur,
                    prev_map: &s.prev_map,
                    config: &cfg,
                    representative: &rep,
                    seed,
                    frame: 2,
                };
                let mut ids = s.prev_map.ids.clone();
                // Start from the wrong ids everywhere on the boundary.
                for site in &sites {
                    ids[site.block] = if ids[site.block] == 1 { 2 } else { 1 };
                }
                let mut vectors = vectors_of(&s.prev_map);
                pool.install(|| optimise(&ctx, &sites, &mut ids, &mut vectors));
                Ok((ids, vectors))
            };
        let a = run(7, 1)?;
        assert_eq!(a, run(7, 4)?);
        assert_eq!(a, run(7, 1)?);
        Ok(())
    }

    #[test]
    fn sampler_restores_the_true_boundary_at_low_temperature() {
        let s = scene();
        let cfg = MrfConfig::default();
        let rep = BTreeMap::new();
        let sites = contested(&s.prev_map.grid);
        let ctx = Context {
            prev_gray: &s.prev,
            cur_gray: &s.cur,
            prev_map: &s.prev_map,
            config: &cfg,
            representative: &rep,
            seed: 3,
            frame: 2,
        };
        let mut ids = s.prev_map.ids.clone();
        for site in &sites {
            ids[site.block] = if ids[site.block] == 1 { 2 } else { 1 };
        }
        let mut vectors = vectors_of(&s.prev_map);
        let stats = optimise(&ctx, &sites, &mut ids, &mut vectors);
        assert!(stats.iterations >= 1);
        let g = s.prev_map.grid;
        for by in 1..7 {
            assert_eq!(ids[g.index(5, by)], 1, "row {by}");
            assert_eq!(ids[g.index(6, by)], 2, "row {by}");
        }
    }

    #[test]
    fn a_change_does_not_propagate_within_a_sweep() {
        // Site A's new state must not be seen by site B in the same sweep: B's result is the
        // same whether A is swept alongside it or not, although A changes and is B's
        // neighbour.
        let s = scene();
        let cfg = MrfConfig {
            initial_temperature: 1e-6,
            min_temperature: 1e-6,
            ..MrfConfig::default()
        };
        let rep = BTreeMap::new();
        let g = s.prev_map.grid;
        let ctx = Context {
            prev_gray: &s.prev,
            cur_gray: &s.cur,
            prev_map: &s.prev_map,
            config: &cfg,
            representative: &rep,
            seed: 3,
            frame: 2,
        };
        let all = contested(&g);
        let mut ids = s.prev_map.ids.clone();
        for site in &all {
            ids[site.block] = if ids[site.block] == 1 { 2 } else { 1 };
        }
        let vectors = vectors_of(&s.prev_map);
        let a = all
            .iter()
            .find(|x| x.block == g.index(5, 3))
            .cloned()
            .into_iter()
            .collect::<Vec<_>>();
        let b = all
            .iter()
            .find(|x| x.block == g.index(5, 4))
            .cloned()
            .into_iter()
            .collect::<Vec<_>>();
        let together: Vec<GibbsSite> = a.iter().chain(&b).cloned().collect();
        let out_ab = sweep(&ctx, &together, &ids, &vectors, 0);
        let out_b = sweep(&ctx, &b, &ids, &vectors, 0);
        assert_ne!(out_ab[0].0, ids[g.index(5, 3)], "A changes id in the sweep");
        assert_eq!(out_ab[1], out_b[0], "B saw A's new state");
        // With A's change applied first (sequential update), B's energies differ.
        let mut seq = ids.clone();
        seq[g.index(5, 3)] = out_ab[0].0;
        assert_ne!(
            site_energies(&ctx, &b[0], &seq, &vectors),
            site_energies(&ctx, &b[0], &ids, &vectors)
        );
    }

    #[test]
    fn proposals_are_the_candidates_own_vectors_and_unit_steps() {
        let g = BlockGrid::for_frame(32, 32);
        let mut vectors = vec![None; g.len()];
        let mut ids = vec![0; g.len()];
        let c1 = Candidate {
            id: 1,
            vector: [5, 5],
            sad: 0,
            rounded: true,
        };
        let c2 = Candidate {
            id: 2,
            vector: [2, 0],
            sad: 0,
            rounded: true,
        };
        let site = GibbsSite {
            block: g.index(1, 1),
            candidates: vec![c1, c2],
        };
        ids[site.block] = 2;
        vectors[site.block] = Some([2, 1]);
        ids[g.index(0, 0)] = 1;
        vectors[g.index(0, 0)] = Some([-3, 1]);
        ids[g.index(2, 2)] = 2;
        vectors[g.index(2, 2)] = Some([2, 0]);
        // Id 1 is not the current id: its own vector and its neighbour's.
        assert_eq!(
            proposals(&site, &c1, &g, &ids, &vectors, 24, None),
            vec![[5, 5], [-3, 1]]
        );
        // Id 2 is current: current, own, neighbour (same as own), ±1 steps of current.
        assert_eq!(
            proposals(&site, &c2, &g, &ids, &vectors, 24, None),
            vec![[2, 1], [2, 0], [3, 1], [1, 1], [2, 2]]
        );
        assert_eq!(
            proposals(&site, &c1, &g, &ids, &vectors, 4, None),
            vec![[-3, 1]]
        );
        // The representative comes first after the current vector, and the tolerance keeps
        // only vectors near it: ±1 px around [2, 0] keeps [2, 1], [2, 0], [3, 1], [1, 1].
        assert_eq!(
            proposals(&site, &c2, &g, &ids, &vectors, 24, Some(([2, 0], 1))),
            vec![[2, 1], [2, 0], [3, 1], [1, 1]]
        );
        // Tolerance 0: the representative only, whatever the block matched.
        assert_eq!(
            proposals(&site, &c1, &g, &ids, &vectors, 24, Some(([4, 4], 0))),
            vec![[4, 4]]
        );
    }

    #[test]
    fn representative_vector_is_the_most_frequent() {
        let g = BlockGrid::for_frame(32, 8);
        let mut map = ObjectMap::empty(g);
        map.ids = vec![1, 1, 1, 2];
        let vectors = vec![Some([3, 0]), Some([3, 0]), Some([1, 0]), Some([0, 2])];
        let rep = representative_vectors(&map, &vectors);
        assert_eq!(rep.get(&1), Some(&[3, 0]));
        assert_eq!(rep.get(&2), Some(&[0, 2]));
    }

    #[test]
    fn temperature_cools_geometrically_to_a_floor() {
        let cfg = MrfConfig::default();
        assert_eq!(temperature(&cfg, 0), cfg.initial_temperature);
        assert!((temperature(&cfg, 1) - cfg.initial_temperature * cfg.cooling).abs() < 1e-12);
        assert_eq!(temperature(&cfg, 10_000), cfg.min_temperature);
    }
}
