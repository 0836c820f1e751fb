//! Validation of the clustered contacts against the per body-pair ground truth that
//! contact detection knows (`pairs_NNNNNN.csv`).
//!
//! The contacts are summed per (body, counterpart) with fdem's convention (a body pair
//! under its lower id, the force on that body) and compared with the truth rows:
//! - **recall**: the share of *significant* truth pairs (normal force above
//!   `significance` x the mean truth normal force of their kind, default 1 %) that the
//!   clustering found;
//! - **precision**: the share of significant clustered pairs (same threshold relative to
//!   the clustered mean) that are truth pairs;
//! - **force error** of each significant pair found: `|F_n,clustered - F_n,truth| /
//!   |F_n,truth|` with vector forces; the tangential error is measured relative to
//!   `|F_n,truth|` too.
//!
//! Body pairs and wall pairs are validated separately. Boundary contacts with an unknown
//! counterpart cannot be matched to a truth row and are only counted.

use crate::cluster::Clustering;
use crate::snapshot::{Counterpart, PairRow};
use crate::vec3::{add, norm, sub};
use serde::Serialize;
use std::collections::BTreeMap;

/// Default significance threshold: pairs carrying more than 1 % of the mean normal force.
pub const DEFAULT_SIGNIFICANCE: f64 = 0.01;

/// Validation of one kind of pair (body-body or body-wall).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PairValidation {
    /// Pairs in the ground truth.
    pub truth_pairs: usize,
    /// Pairs found by the clustering.
    pub clustered_pairs: usize,
    /// Truth pairs above the significance threshold.
    pub significant_truth_pairs: usize,
    /// Of which found by the clustering.
    pub recalled: usize,
    /// `recalled / significant_truth_pairs` (`None` without significant truth pairs).
    pub recall: Option<f64>,
    /// Clustered pairs above the significance threshold.
    pub significant_clustered_pairs: usize,
    /// Of which in the ground truth.
    pub confirmed: usize,
    /// `confirmed / significant_clustered_pairs`.
    pub precision: Option<f64>,
    /// Recall over all truth pairs, however small.
    pub recall_all: Option<f64>,
    /// Precision over all clustered pairs, however small.
    pub precision_all: Option<f64>,
    /// Mean relative normal-force error over the significant pairs found.
    pub mean_force_error: Option<f64>,
    /// Largest relative normal-force error over the significant pairs found.
    pub max_force_error: Option<f64>,
    /// Largest tangential-force error relative to the truth normal force.
    pub max_tangential_error: Option<f64>,
    /// Significant pairs found whose normal-force error exceeds 5 %.
    pub pairs_over_5_percent: usize,
    /// The significant pair with the largest normal-force error: body and counterpart.
    pub worst_pair: Option<(u32, Counterpart)>,
}

/// Validation of one snapshot.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Validation {
    /// The significance threshold used (fraction of the mean normal force).
    pub significance: f64,
    /// Body-body pairs (particles and boundary bodies).
    pub body_pairs: PairValidation,
    /// Body-wall pairs.
    pub wall_pairs: PairValidation,
    /// Boundary contacts with an unknown counterpart (not comparable with the truth).
    pub unknown_contacts: usize,
}

type Key = (u32, Counterpart);

/// Sums of normal and tangential force per pair.
type Sums = BTreeMap<Key, ([f64; 3], [f64; 3])>;

fn validate_kind(clustered: &Sums, truth: &Sums, significance: f64) -> PairValidation {
    let mean = |s: &Sums| {
        if s.is_empty() {
            0.0
        } else {
            s.values().map(|v| norm(v.0)).sum::<f64>() / s.len() as f64
        }
    };
    let ratio = |a: usize, b: usize| (b > 0).then(|| a as f64 / b as f64);
    let (truth_threshold, clustered_threshold) =
        (significance * mean(truth), significance * mean(clustered));
    let mut v = PairValidation {
        truth_pairs: truth.len(),
        clustered_pairs: clustered.len(),
        ..PairValidation::default()
    };
    let recalled_all = truth.keys().filter(|k| clustered.contains_key(k)).count();
    let confirmed_all = clustered.keys().filter(|k| truth.contains_key(k)).count();
    v.recall_all = ratio(recalled_all, truth.len());
    v.precision_all = ratio(confirmed_all, clustered.len());
    let mut errors = Vec::new();
    for (key, (tn, tt)) in truth {
        let f = norm(*tn);
        if f <= truth_threshold {
            continue;
        }
        v.significant_truth_pairs += 1;
        let Some((cn, ct)) = clustered.get(key) else {
            continue;
        };
        v.recalled += 1;
        let e = norm(sub(*cn, *tn)) / f;
        let et = norm(sub(*ct, *tt)) / f;
        if e > 0.05 {
            v.pairs_over_5_percent += 1;
        }
        if v.max_force_error.is_none_or(|m| e > m) {
            v.worst_pair = Some(*key);
        }
        v.max_force_error = Some(v.max_force_error.map_or(e, |m: f64| m.max(e)));
        v.max_tangential_error = Some(v.max_tangential_error.map_or(et, |m: f64| m.max(et)));
        errors.push(e);
    }
    v.recall = ratio(v.recalled, v.significant_truth_pairs);
    v.mean_force_error =
        (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64);
    for (key, (cn, _)) in clustered {
        if norm(*cn) <= clustered_threshold {
            continue;
        }
        v.significant_clustered_pairs += 1;
        if truth.contains_key(key) {
            v.confirmed += 1;
        }
    }
    v.precision = ratio(v.confirmed, v.significant_clustered_pairs);
    v
}

/// Compares the contacts of `clustering` with the ground truth `truth` (see the module
/// docs). `significance` is the threshold as a fraction of the mean normal force
/// ([`DEFAULT_SIGNIFICANCE`]).
pub fn validate(clustering: &Clustering, truth: &[PairRow], significance: f64) -> Validation {
    let mut clustered: [Sums; 2] = [Sums::new(), Sums::new()];
    let mut unknown_contacts = 0;
    for c in &clustering.contacts {
        let slot = match c.other {
            Counterpart::Body(_) => 0,
            Counterpart::Wall(_) => 1,
            Counterpart::Unknown => {
                unknown_contacts += 1;
                continue;
            }
        };
        let e = clustered[slot]
            .entry((c.body, c.other))
            .or_insert(([0.0; 3], [0.0; 3]));
        e.0 = add(e.0, c.normal_force);
        e.1 = add(e.1, c.tangential_force);
    }
    let mut reference: [Sums; 2] = [Sums::new(), Sums::new()];
    for p in truth {
        let slot = match p.counterpart {
            Counterpart::Body(_) => 0,
            Counterpart::Wall(_) => 1,
            Counterpart::Unknown => continue,
        };
        let e = reference[slot]
            .entry((p.body, p.counterpart))
            .or_insert(([0.0; 3], [0.0; 3]));
        e.0 = add(e.0, p.normal_force);
        e.1 = add(e.1, p.tangential_force);
    }
    Validation {
        significance,
        body_pairs: validate_kind(&clustered[0], &reference[0], significance),
        wall_pairs: validate_kind(&clustered[1], &reference[1], significance),
        unknown_contacts,
    }
}
