//! The per-step scan of the surface nodes: every position and velocity finite, the largest
//! drift from where the mean motion expects each node's reference (whether the candidate
//! lists must be renewed), and the fastest node (the tunnelling bound and the guards).
//!
//! A rigid body with a frame need not have its nodes read. Its caller bounds its nodes'
//! speeds and says whether they are finite ([`RigidMotion`], from the body's state), and
//! its pose bounds their drift (`crate::rigid_frames`). Each use of the scan is a
//! comparison with a threshold, and a bound decides it as the nodes would wherever the
//! bound is on the safe side of it: a drift bound clearly below the allowance renews
//! nothing, and a speed bound within the tunnelling bound (`2 v dt <=` the depth limit)
//! cannot be the step that grows the depth limit (a bound above the guards' thresholds only
//! turns exact checks on, which find nothing the nodes' speeds would not have let them
//! find). Elsewhere, and for a body whose values are not all finite, its nodes are read as
//! everyone else's: the errors, the renewals and the contacts are the same, bit for bit.

use rayon::prelude::*;

use crate::ContactSurface;
use crate::broad::CHUNK;
use crate::mean_motion::{Expected, drift2};
use crate::rigid_frames::{NodeRun, NodeVelocities, RigidFrames, RigidMotion};
use crate::vec3::{is_finite, norm2};

/// Framed bodies per parallel work item of the scan.
const BODY_CHUNK: usize = 256;

/// How far below its threshold a body's drift bound must lie to stand in for its nodes
/// (relative): far above the round-off of the bound and of the nodes' own drifts (about
/// 1e-16 of the coordinates), so a body that passes is below the threshold node by node.
const BOUND_MARGIN: f64 = 1e-6;

/// Result of the per-step scan of the surface nodes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scan {
    /// First non-finite position or velocity: (surface index, is_velocity).
    pub(crate) bad: Option<(usize, bool)>,
    /// The largest drift (squared, m^2): exact where a node was read, a body's bound where
    /// its bound stood in (then below the allowance).
    pub(crate) max_drift2: f64,
    /// The largest speed (squared, m^2/s^2): exact where a node was read, a body's bound
    /// where its bound stood in (then within the tunnelling bound).
    pub(crate) max_speed2: f64,
    /// The surface index of the fastest node (the first of equals; a body's first node
    /// where its bound is the largest).
    pub(crate) fastest: usize,
}

impl Scan {
    const EMPTY: Scan = Scan {
        bad: None,
        max_drift2: 0.0,
        max_speed2: 0.0,
        fastest: 0,
    };

    pub(crate) fn merge(self, o: Scan) -> Scan {
        let bad = match (self.bad, o.bad) {
            (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
            (a, b) => a.or(b),
        };
        let (max_speed2, fastest) = if o.max_speed2 > self.max_speed2
            || (o.max_speed2 == self.max_speed2 && o.fastest < self.fastest)
        {
            (o.max_speed2, o.fastest)
        } else {
            (self.max_speed2, self.fastest)
        };
        Scan {
            bad,
            max_drift2: self.max_drift2.max(o.max_drift2),
            max_speed2,
            fastest,
        }
    }

    /// Surface node `k` at its speed squared `v2`.
    #[inline(always)]
    fn speed(&mut self, k: usize, v2: f64) {
        if v2 > self.max_speed2 {
            self.max_speed2 = v2;
            self.fastest = k;
        }
    }
}

/// What the scan reads: the state, and the nodes' references once the lists were built.
pub(crate) struct Nodes<'a> {
    pub(crate) surface: &'a ContactSurface,
    pub(crate) positions: &'a [[f64; 3]],
    /// The node velocities: a framed body's from its motion when given.
    pub(crate) velocities: NodeVelocities<'a>,
    pub(crate) reference: Option<&'a [[f64; 3]]>,
    pub(crate) expected: Option<&'a Expected>,
}

impl Nodes<'_> {
    /// Reads surface nodes `range` into `s`.
    fn read(&self, range: std::ops::Range<usize>, s: &mut Scan) {
        let nodes = &self.surface.surface_nodes;
        for k in range {
            let x = self.positions[nodes[k]];
            let v = self.velocities.of_surface_node(self.surface, k, x);
            if s.bad.is_none() {
                if !is_finite(x) {
                    s.bad = Some((k, false));
                } else if !is_finite(v) {
                    s.bad = Some((k, true));
                }
            }
            if let Some(r) = self.reference {
                s.max_drift2 = s.max_drift2.max(drift2(self.expected, x, r[k]));
            }
            s.speed(k, norm2(v));
        }
    }

    /// Reads the drifts alone of surface nodes `range` into `s`.
    fn read_drifts(&self, range: std::ops::Range<usize>, s: &mut Scan) {
        let Some(r) = self.reference else {
            return;
        };
        let nodes = &self.surface.surface_nodes;
        for k in range {
            let x = self.positions[nodes[k]];
            s.max_drift2 = s.max_drift2.max(drift2(self.expected, x, r[k]));
        }
    }

    /// Scans every surface node.
    pub(crate) fn scan(&self) -> Scan {
        let n = self.surface.surface_nodes.len();
        (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|chunk| {
                let mut s = Scan::EMPTY;
                self.read(chunk * CHUNK..((chunk + 1) * CHUNK).min(n), &mut s);
                s
            })
            .reduce(|| Scan::EMPTY, Scan::merge)
    }

    /// Scans the nodes the frames do not stand in for one by one, and each framed body
    /// with a node run from its caller's `motions`, against the drift `allowance` (m) and
    /// the tunnelling bound of a step `dt` (s) under the depth limit `depth_limit` (m).
    pub(crate) fn scan_framed(
        &self,
        frames: &RigidFrames,
        motions: &[RigidMotion],
        (allowance, dt, depth_limit): (f64, f64, f64),
    ) -> Scan {
        let read = frames
            .scanned_nodes()
            .par_iter()
            .map(|range| {
                let mut s = Scan::EMPTY;
                self.read(range.clone(), &mut s);
                s
            })
            .reduce(|| Scan::EMPTY, Scan::merge);
        let runs = frames.node_runs();
        let limits = Limits {
            allowance,
            dt,
            depth_limit,
        };
        let bodies = runs
            .par_chunks(BODY_CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut s = Scan::EMPTY;
                for (i, run) in chunk.iter().enumerate() {
                    if let Some(run) = run {
                        let k = c * BODY_CHUNK + i;
                        self.body(frames, k, (*run, motions[k]), limits, &mut s);
                    }
                }
                s
            })
            .reduce(|| Scan::EMPTY, Scan::merge);
        read.merge(bodies)
    }

    /// Framed body `k` (its nodes `run`, its caller's `motion`) into `s`.
    fn body(
        &self,
        frames: &RigidFrames,
        k: usize,
        (run, motion): (NodeRun, RigidMotion),
        limits: Limits,
        s: &mut Scan,
    ) {
        let range = run.start..run.start + run.len;
        let v = motion.speed_bound;
        // The tunnelling bound's comparison (`ContactModel::check_scan`), with room for the
        // round-off of squaring the bound and taking the root again.
        let tunnelling = 2.0 * v * limits.dt * (1.0 + BOUND_MARGIN) > limits.depth_limit;
        if !motion.finite || !v.is_finite() || tunnelling {
            self.read(range, s);
            return;
        }
        s.speed(run.start, v * v);
        if self.reference.is_none() {
            return;
        }
        match bound_within(frames, k, self.expected, limits.allowance) {
            Some(bound) => s.max_drift2 = s.max_drift2.max(bound * bound),
            None => self.read_drifts(range, s),
        }
    }
}

/// The thresholds the scan's bounds are held against.
#[derive(Clone, Copy, Debug)]
struct Limits {
    allowance: f64,
    dt: f64,
    depth_limit: f64,
}

/// Framed body `k`'s drift bound (m) when it shows every node of the body clearly within
/// `threshold` (m) of where its reference is expected (`None` where it cannot tell): the
/// bound, the mismatch of nodes and reference each way, and the relative margin.
pub(crate) fn bound_within(
    frames: &RigidFrames,
    k: usize,
    expected: Option<&Expected>,
    threshold: f64,
) -> Option<f64> {
    frames
        .drift_bound(k, expected)
        .filter(|bound| bound * (1.0 + BOUND_MARGIN) + 4.0 * frames.mismatch() <= threshold)
}
