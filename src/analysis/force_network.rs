//! Connectivity of the force networks during an impact (Kondic et al. Sec. IV A, Figs
//! 22-23): the zeroth Betti number B0 (the number of connected components) of the set of
//! grains whose force exceeds a threshold, as a function of the threshold.
//!
//! K threshold a particle-scale binary image (a particle is white when its force is
//! above the threshold, black when at or below) and count its connected white regions
//! with CHOMP. Two white grains touch in that image exactly when they are in contact, so
//! here the image is the graph whose nodes are the white grains and whose edges are the
//! contacts between two of them, and B0 is the number of its connected components
//! (union-find). A grain's force is the sum of the magnitudes of its contact forces
//! (normal or tangential) over all its contacts, walls and intruder included (K Fig 1:
//! "colored according to the total normal force experienced"); walls and the intruder
//! are not nodes. B0 is normalised by the number of grains, the thresholds by the mean
//! normal force per grain (K Fig 22's caption, for both networks).

use crate::rundata::impact::ContactForce;
use anyhow::{Result, bail};
use petgraph::unionfind::UnionFind;
use std::collections::HashMap;

/// Per-grain forces and the grain-grain contacts of one snapshot.
#[derive(Debug, Clone)]
pub(crate) struct Network {
    /// Sum of |F_n| over each grain's contacts (N), in the order of the grain ids given.
    pub normal: Vec<f64>,
    /// Sum of |F_t| (N).
    pub tangential: Vec<f64>,
    /// Grain-grain contacts as indices into the grain list.
    pub edges: Vec<(usize, usize)>,
}

impl Network {
    /// From the touching pairs of a snapshot; `grains` are the ids of the nodes (every
    /// other id is a wall or the intruder).
    pub fn new(grains: &[u64], contacts: &[ContactForce]) -> Network {
        let index: HashMap<u64, usize> =
            grains.iter().enumerate().map(|(k, &id)| (id, k)).collect();
        let mut normal = vec![0.0; grains.len()];
        let mut tangential = vec![0.0; grains.len()];
        let mut edges = Vec::new();
        for c in contacts {
            let (a, b) = (index.get(&c.i).copied(), index.get(&c.j).copied());
            for k in [a, b].into_iter().flatten() {
                normal[k] += c.f_n.abs();
                tangential[k] += c.ft.abs();
            }
            if let (Some(a), Some(b)) = (a, b) {
                edges.push((a, b));
            }
        }
        Network {
            normal,
            tangential,
            edges,
        }
    }

    /// Mean normal force per grain, over all grains (rattlers count with zero).
    pub(crate) fn mean_normal(&self) -> f64 {
        self.normal.iter().sum::<f64>() / self.normal.len().max(1) as f64
    }
}

/// B0 of the grains with `force > threshold` joined by `edges`.
pub(crate) fn b0(force: &[f64], edges: &[(usize, usize)], threshold: f64) -> usize {
    let white: Vec<bool> = force.iter().map(|&f| f > threshold).collect();
    let mut uf = UnionFind::<usize>::new(force.len());
    let merges = edges
        .iter()
        .filter(|&&(a, b)| white[a] && white[b] && uf.union(a, b))
        .count();
    white.iter().filter(|&&w| w).count() - merges
}

/// B0 / N over the thresholds `0, step, ..., max` (in units of the mean normal force) of
/// both networks of one snapshot.
#[derive(Debug, Clone, serde::Serialize)]
pub struct B0Curves {
    pub thresholds: Vec<f64>,
    pub normal: Vec<f64>,
    pub tangential: Vec<f64>,
    /// The force unit: mean normal force per grain (N).
    pub mean_normal: f64,
    pub grains: usize,
    pub grain_contacts: usize,
}

pub(crate) fn curves(net: &Network, max: f64, step: f64) -> Result<B0Curves> {
    let n = net.normal.len();
    let unit = net.mean_normal();
    if n == 0 || unit.is_nan() || unit <= 0.0 {
        bail!(
            "no grains with a normal force: B0 is not defined ({n} grains, mean normal force {unit:e} N)"
        );
    }
    let count = (max / step).round() as usize;
    let thresholds: Vec<f64> = (0..=count).map(|k| k as f64 * step).collect();
    let curve = |f: &[f64]| -> Vec<f64> {
        thresholds
            .iter()
            .map(|&t| b0(f, &net.edges, t * unit) as f64 / n as f64)
            .collect()
    };
    Ok(B0Curves {
        normal: curve(&net.normal),
        tangential: curve(&net.tangential),
        thresholds,
        mean_normal: unit,
        grains: n,
        grain_contacts: net.edges.len(),
    })
}

/// Trapezoid integral of `y` over the equally spaced `x`.
pub fn integral(x: &[f64], y: &[f64]) -> f64 {
    x.windows(2)
        .zip(y.windows(2))
        .map(|(x, y)| 0.5 * (x[1] - x[0]) * (y[0] + y[1]))
        .sum()
}

/// L1 distance of two curves on the same thresholds over the integral of `b` (the
/// reference), the native-vs-reference distance of Figs 22-23.
pub(crate) fn relative_l1(x: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let diff: Vec<f64> = a.iter().zip(b).map(|(p, q)| (p - q).abs()).collect();
    integral(x, &diff) / integral(x, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(i: u64, j: u64, f_n: f64, ft: f64) -> ContactForce {
        ContactForce { i, j, f_n, ft }
    }

    /// A chain 1-2-3 and a pair 4-5 and a lone grain 6, hand-counted.
    #[test]
    fn b0_counts_components_of_the_grains_above_threshold() {
        let grains = [1, 2, 3, 4, 5, 6];
        // 99 is a wall: its force counts for grain 6, but it is not a node.
        let contacts = [
            c(1, 2, 2.0, 0.0),
            c(2, 3, 2.0, 1.0),
            c(4, 5, 5.0, 0.0),
            c(6, 99, 1.0, 0.5),
        ];
        let net = Network::new(&grains, &contacts);
        assert_eq!(net.normal, vec![2.0, 4.0, 2.0, 5.0, 5.0, 1.0]);
        assert_eq!(net.tangential, vec![0.0, 1.0, 1.0, 0.0, 0.0, 0.5]);
        assert_eq!(net.edges.len(), 3);
        // Everyone white: {1,2,3}, {4,5}, {6}.
        assert_eq!(b0(&net.normal, &net.edges, 0.0), 3);
        // Above 1.5: grain 6 black -> 2.
        assert_eq!(b0(&net.normal, &net.edges, 1.5), 2);
        // Above 3: only 2 (alone: its neighbours are black) and {4,5} -> 2.
        assert_eq!(b0(&net.normal, &net.edges, 3.0), 2);
        // Above 4: only {4,5}; "above" is strict (a force equal to it is black).
        assert_eq!(b0(&net.normal, &net.edges, 4.0), 1);
        assert_eq!(b0(&net.normal, &net.edges, 5.0), 0);
        // Tangential above 0: 2 and 3 joined, 6 alone -> 2.
        assert_eq!(b0(&net.tangential, &net.edges, 0.0), 2);
    }

    /// A ring of 4 grains with one weak contact: cutting it gives 2 clusters of 2, not 1;
    /// curves are B0 / N on thresholds scaled by the mean normal force.
    #[test]
    fn curves_normalise_by_grains_and_mean_normal_force() {
        let grains = [1, 2, 3, 4];
        let contacts = [
            c(1, 2, 4.0, 0.0),
            c(2, 3, 1.0, 0.0),
            c(3, 4, 4.0, 0.0),
            c(4, 1, 1.0, 0.0),
        ];
        let net = Network::new(&grains, &contacts);
        assert_eq!(net.mean_normal(), 5.0);
        // A grain's force is 5 each: at threshold 0 one ring, above 1 (5 N) nothing.
        let k = curves(&net, 1.0, 0.5).unwrap();
        assert_eq!(k.thresholds, vec![0.0, 0.5, 1.0]);
        assert_eq!(k.normal, vec![0.25, 0.25, 0.0]);
        assert_eq!(k.tangential, vec![0.0, 0.0, 0.0]);
        assert!((integral(&k.thresholds, &k.normal) - 0.1875).abs() < 1e-15);
        assert!((relative_l1(&k.thresholds, &k.normal, &k.normal)).abs() < 1e-15);
        assert!(curves(&Network::new(&grains, &[]), 1.0, 0.5).is_err());
    }
}
