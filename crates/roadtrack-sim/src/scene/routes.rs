//! Vehicle and pedestrian routes and entries, and the walking network that builds
//! pedestrian routes by shortest paths.

use super::geometry::{Polyline, Vec2, norm, sub};
use std::collections::BinaryHeap;

/// A stretch of a route shared with other routes (a lane between junctions); vehicles
/// look for their leader segment by segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoutePart {
    /// Segment id (shared by every route that uses the same lane stretch).
    pub segment: usize,
    /// Route arc length where the part starts, m.
    pub start_s: f64,
    /// Route arc length where it ends, m.
    pub end_s: f64,
}

/// A path vehicles follow from an entry to an exit.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleRoute {
    /// The centre line.
    pub path: Polyline,
    /// Its lane stretches, in order, covering `[0, length]`.
    pub parts: Vec<RoutePart>,
    /// Stop line (arc length the front must not pass on red) and its signal group.
    pub stop: Option<(f64, u8)>,
    /// Turn: `[start_s, end_s, max_speed_mps]`, driven at most at that speed.
    pub turn: Option<[f64; 3]>,
    /// Lane index on a multi-lane road where lane changes are allowed (0 = outer/right).
    pub lane: Option<usize>,
    /// Speed limit, m/s.
    pub speed_limit_mps: f64,
}

impl VehicleRoute {
    /// The part containing arc length `s` (the last one beyond the end).
    pub fn part_index(&self, s: f64) -> usize {
        self.parts
            .iter()
            .position(|p| s < p.end_s)
            .unwrap_or(self.parts.len().saturating_sub(1))
    }
}

/// Where vehicles arrive: a Poisson stream split over routes.
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleEntry {
    /// Mean arrivals, vehicles/s.
    pub rate_per_s: f64,
    /// Routes and their weights.
    pub routes: Vec<(usize, f64)>,
}

/// A crosswalk on a pedestrian route: between these arc lengths the route is on the
/// crosswalk and needs the given signal group (when the scene has signals).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteCrossing {
    /// Index of the kerb vertex of the route's path (the same on every offset copy).
    pub kerb_vertex: usize,
    /// Arc length of the kerb node where pedestrians wait, m.
    pub kerb_s: f64,
    /// Arc length of the far kerb node, m.
    pub far_s: f64,
    /// Signal group.
    pub group: u8,
}

/// A walking route (centre line; each walker keeps a lateral offset).
#[derive(Debug, Clone, PartialEq)]
pub struct PedestrianRoute {
    /// Centre line.
    pub path: Polyline,
    /// Crosswalks on it, in order.
    pub crossings: Vec<RouteCrossing>,
}

/// Where pedestrian groups arrive.
#[derive(Debug, Clone, PartialEq)]
pub struct PedestrianEntry {
    /// Mean group arrivals, groups/s.
    pub rate_per_s: f64,
    /// Routes and their weights.
    pub routes: Vec<(usize, f64)>,
}

/// A small walking network for building pedestrian routes by shortest paths.
#[derive(Default)]
pub(super) struct Network {
    nodes: Vec<Vec2>,
    edges: Vec<Vec<(usize, Option<u8>)>>,
}

impl Network {
    pub(super) fn node(&mut self, p: Vec2) -> usize {
        if let Some(i) = self.nodes.iter().position(|q| norm(sub(*q, p)) < 1e-6) {
            return i;
        }
        self.nodes.push(p);
        self.edges.push(Vec::new());
        self.nodes.len() - 1
    }

    pub(super) fn edge(&mut self, a: usize, b: usize, group: Option<u8>) {
        if !self.edges[a].iter().any(|e| e.0 == b) {
            self.edges[a].push((b, group));
            self.edges[b].push((a, group));
        }
    }

    /// Shortest path (Dijkstra) between two nodes as node indices.
    pub(super) fn path(&self, from: usize, to: usize) -> Option<Vec<usize>> {
        #[derive(PartialEq)]
        struct Item(f64, usize);
        impl Eq for Item {}
        impl PartialOrd for Item {
            fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Item {
            fn cmp(&self, o: &Self) -> std::cmp::Ordering {
                o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
            }
        }
        let n = self.nodes.len();
        let mut dist = vec![f64::INFINITY; n];
        let mut prev = vec![usize::MAX; n];
        let mut heap = BinaryHeap::new();
        dist[from] = 0.0;
        heap.push(Item(0.0, from));
        while let Some(Item(d, u)) = heap.pop() {
            if d > dist[u] {
                continue;
            }
            for &(v, _) in &self.edges[u] {
                let nd = d + norm(sub(self.nodes[u], self.nodes[v]));
                if nd < dist[v] {
                    dist[v] = nd;
                    prev[v] = u;
                    heap.push(Item(nd, v));
                }
            }
        }
        if !dist[to].is_finite() {
            return None;
        }
        let mut out = vec![to];
        let mut u = to;
        while u != from {
            u = prev[u];
            out.push(u);
        }
        out.reverse();
        Some(out)
    }

    /// One route per ordered pair of distinct ends, with entry weights from `weight`.
    pub(super) fn routes(
        &self,
        ends: &[usize],
        rate_per_s: f64,
        weight: impl Fn(Vec2, Vec2) -> f64,
    ) -> (Vec<PedestrianRoute>, Vec<PedestrianEntry>) {
        let mut routes = Vec::new();
        let mut entries = Vec::new();
        for &from in ends {
            let mut entry = PedestrianEntry {
                rate_per_s,
                routes: Vec::new(),
            };
            for &to in ends {
                if to == from {
                    continue;
                }
                let Some(nodes) = self.path(from, to) else {
                    continue;
                };
                let path = Polyline::new(nodes.iter().map(|&i| self.nodes[i]).collect());
                let mut crossings = Vec::new();
                for (k, pair) in nodes.windows(2).enumerate() {
                    let group = self.edges[pair[0]]
                        .iter()
                        .find(|e| e.0 == pair[1])
                        .and_then(|e| e.1);
                    if let Some(g) = group {
                        crossings.push(RouteCrossing {
                            kerb_vertex: k,
                            kerb_s: path.vertex_s(k),
                            far_s: path.vertex_s(k + 1),
                            group: g,
                        });
                    }
                }
                let w = weight(self.nodes[from], self.nodes[to]);
                routes.push(PedestrianRoute { path, crossings });
                entry.routes.push((routes.len() - 1, w));
            }
            entries.push(entry);
        }
        (routes, entries)
    }
}
