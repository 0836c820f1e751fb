//! Contact statistics: count, coordination number, mean forces and the distribution of
//! the normalised normal force (paper Figs 9/10, Table 5).

use crate::cluster::{Clustering, ContactKind};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};

/// Width of the histogram bins of `F_n / mean(F_n)`. Fixed, so that runs overlay and the
/// first bin is exactly the weak contacts (< 0.2).
pub const BIN_WIDTH: f64 = 0.2;
/// Number of bins: they cover `[0, 8)`; larger ratios are counted as overflow.
pub const BINS: usize = 40;
/// Contacts with `F_n / mean(F_n)` above this are strong (paper section 2.4).
pub const STRONG_RATIO: f64 = 4.0;
/// Contacts with `F_n / mean(F_n)` below this are weak (paper section 2.4).
pub const WEAK_RATIO: f64 = 0.2;

/// Histogram of `F_n / mean(F_n)` over the particle contacts, bins `[k w, (k + 1) w)` with
/// `w = BIN_WIDTH`.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Histogram {
    /// Bin width ([`BIN_WIDTH`]).
    pub bin_width: f64,
    /// Contacts per bin ([`BINS`] bins from 0).
    pub counts: Vec<usize>,
    /// Contacts at or beyond the last bin's upper edge.
    pub overflow: usize,
    /// Probability density per bin: `count / (contacts x bin_width)` (0 without contacts).
    pub density: Vec<f64>,
}

impl Histogram {
    /// Bins the given normalised forces.
    pub fn of(ratios: &[f64]) -> Histogram {
        let mut counts = vec![0usize; BINS];
        let mut overflow = 0;
        for &r in ratios {
            let k = (r / BIN_WIDTH).floor();
            if k >= 0.0 && (k as usize) < BINS {
                counts[k as usize] += 1;
            } else {
                overflow += 1;
            }
        }
        let n = ratios.len();
        let density = counts
            .iter()
            .map(|&c| {
                if n > 0 {
                    c as f64 / (n as f64 * BIN_WIDTH)
                } else {
                    0.0
                }
            })
            .collect();
        Histogram {
            bin_width: BIN_WIDTH,
            counts,
            overflow,
            density,
        }
    }

    /// Centre of bin `k`.
    pub fn centre(&self, k: usize) -> f64 {
        (k as f64 + 0.5) * self.bin_width
    }
}

/// Where the particle count of the coordination number came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ParticleCount {
    /// Given by the caller (for example from the run's `summary.json`).
    Given,
    /// The particles that appear in the snapshot (particles without any contact, rattlers,
    /// are then not counted).
    Snapshot,
}

/// Statistics of the particle contacts of one snapshot.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Statistics {
    /// Time of the snapshot (s).
    pub time: f64,
    /// Number of particle-particle contacts.
    pub contacts: usize,
    /// Number of boundary contacts (walls, boundary bodies, unpaired clusters).
    pub boundary_contacts: usize,
    /// Particles used for the coordination number.
    pub particles: usize,
    /// Where `particles` came from.
    pub particles_from: ParticleCount,
    /// Particles with at least one particle contact.
    pub particles_in_contact: usize,
    /// Mean coordination number `2 contacts / particles` (0 without particles).
    pub coordination_number: f64,
    /// Body pairs that have more than one contact (clusters that did not merge).
    pub pairs_with_several_contacts: usize,
    /// Mean normal force magnitude over the particle contacts (N; 0 without contacts).
    pub mean_normal_force: f64,
    /// Largest normal force magnitude (N).
    pub max_normal_force: f64,
    /// Mean tangential force magnitude (N).
    pub mean_tangential_force: f64,
    /// Share of contacts with `F_n / mean(F_n) > 4`.
    pub strong_share: f64,
    /// Share of contacts with `F_n / mean(F_n) < 0.2`.
    pub weak_share: f64,
    /// Distribution of `F_n / mean(F_n)`.
    pub histogram: Histogram,
}

/// Statistics of the particle contacts of `clustering`. `particles` is the number of
/// particles of the specimen for the coordination number; `None` counts the particles
/// seen in the snapshot.
pub fn statistics(clustering: &Clustering, particles: Option<usize>) -> Statistics {
    let particle: Vec<_> = clustering
        .contacts
        .iter()
        .filter(|c| c.kind == ContactKind::Particle)
        .collect();
    let n = particle.len();
    let forces: Vec<f64> = particle.iter().map(|c| c.normal_magnitude()).collect();
    let mean = if n > 0 {
        forces.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    let ratios: Vec<f64> = if mean > 0.0 {
        forces.iter().map(|f| f / mean).collect()
    } else {
        Vec::new()
    };
    let share = |pred: &dyn Fn(f64) -> bool| {
        if ratios.is_empty() {
            0.0
        } else {
            ratios.iter().filter(|&&r| pred(r)).count() as f64 / ratios.len() as f64
        }
    };
    let (count, from) = match particles {
        Some(p) => (p, ParticleCount::Given),
        None => (clustering.particles_seen, ParticleCount::Snapshot),
    };
    let mut in_contact = BTreeSet::new();
    let mut per_pair: BTreeMap<(u32, crate::Counterpart), usize> = BTreeMap::new();
    for c in &particle {
        in_contact.insert(c.body);
        if let crate::Counterpart::Body(o) = c.other {
            in_contact.insert(o);
        }
        *per_pair.entry((c.body, c.other)).or_default() += 1;
    }
    Statistics {
        time: clustering.time,
        contacts: n,
        boundary_contacts: clustering.contacts.len() - n,
        particles: count,
        particles_from: from,
        particles_in_contact: in_contact.len(),
        coordination_number: if count > 0 {
            2.0 * n as f64 / count as f64
        } else {
            0.0
        },
        pairs_with_several_contacts: per_pair.values().filter(|&&k| k > 1).count(),
        mean_normal_force: mean,
        max_normal_force: forces.iter().copied().fold(0.0, f64::max),
        mean_tangential_force: if n > 0 {
            particle
                .iter()
                .map(|c| c.tangential_magnitude())
                .sum::<f64>()
                / n as f64
        } else {
            0.0
        },
        strong_share: share(&|r| r > STRONG_RATIO),
        weak_share: share(&|r| r < WEAK_RATIO),
        histogram: Histogram::of(&ratios),
    }
}

/// One row of a Table 5-style comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TableRow {
    /// The run's label.
    pub label: String,
    /// Mean normal contact force (N).
    pub mean_normal_force: f64,
    /// Ratio to the first run's mean (`None` when the first mean is 0).
    pub ratio_to_first: Option<f64>,
    /// Particle contacts.
    pub contacts: usize,
    /// Mean coordination number.
    pub coordination_number: f64,
}

/// Table 5 of the paper for several runs: mean normal force and its ratio to the first.
pub fn table(runs: &[(String, &Statistics)]) -> Vec<TableRow> {
    let first = runs.first().map_or(0.0, |r| r.1.mean_normal_force);
    runs.iter()
        .map(|(label, s)| TableRow {
            label: label.clone(),
            mean_normal_force: s.mean_normal_force,
            ratio_to_first: (first > 0.0).then(|| s.mean_normal_force / first),
            contacts: s.contacts,
            coordination_number: s.coordination_number,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_bins_are_half_open_and_count_overflow() {
        let h = Histogram::of(&[0.0, 0.1999, 0.2, 7.9999, 8.0, 12.0]);
        assert_eq!(h.counts[0], 2);
        assert_eq!(h.counts[1], 1);
        assert_eq!(h.counts[BINS - 1], 1);
        assert_eq!(h.overflow, 2);
        let total: f64 = h.density.iter().sum::<f64>() * h.bin_width;
        assert!((total - 4.0 / 6.0).abs() < 1e-12);
    }
}
