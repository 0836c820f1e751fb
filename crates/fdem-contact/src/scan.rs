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
        let finite = match (self.reference, self.expected) {
            (Some(r), e) => self.read_with(range.clone(), s, |k, x| drift2(e, x, r[k])),
            (None, _) => self.read_with(range.clone(), s, |_, _| 0.0),
        };
        if !finite && s.bad.is_none() {
            s.bad = self.first_bad(range);
        }
    }

    /// The speeds of surface nodes `range`, and their drifts `drift(k, x)` (squared), into
    /// `s`; whether every position and velocity read was finite. The loop has no branch
    /// on the values but the fastest node's: finiteness is summed as `x - x` (zero for a
    /// finite `x`, NaN otherwise) and the largest drift is kept by comparison, which
    /// passes over a NaN as `f64::max` does, so `s` is the same as node by node.
    #[allow(clippy::eq_op)] // `x - x` is the finiteness test, on purpose.
    #[inline(always)]
    fn read_with(
        &self,
        range: std::ops::Range<usize>,
        s: &mut Scan,
        drift: impl Fn(usize, [f64; 3]) -> f64,
    ) -> bool {
        let nodes = &self.surface.surface_nodes;
        let mut defect = 0.0;
        let mut max_drift2 = s.max_drift2;
        for k in range {
            let x = self.positions[nodes[k]];
            let v = self.velocities.of_surface_node(self.surface, k, x);
            for d in 0..3 {
                defect += (x[d] - x[d]) + (v[d] - v[d]);
            }
            let d2 = drift(k, x);
            if d2 > max_drift2 {
                max_drift2 = d2;
            }
            s.speed(k, norm2(v));
        }
        s.max_drift2 = max_drift2;
        defect == 0.0
    }

    /// The first of surface nodes `range` with a position or velocity that is not finite:
    /// (surface index, is_velocity).
    #[cold]
    fn first_bad(&self, mut range: std::ops::Range<usize>) -> Option<(usize, bool)> {
        let nodes = &self.surface.surface_nodes;
        range.find_map(|k| {
            let x = self.positions[nodes[k]];
            let v = self.velocities.of_surface_node(self.surface, k, x);
            if !is_finite(x) {
                Some((k, false))
            } else {
                (!is_finite(v)).then_some((k, true))
            }
        })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mean_motion::MeanMotion;

    /// The scan node by node, as it was written before its loop lost its branches.
    fn node_by_node(nodes: &Nodes<'_>) -> Scan {
        let mut s = Scan::EMPTY;
        for k in 0..nodes.surface.surface_nodes.len() {
            let x = nodes.positions[nodes.surface.surface_nodes[k]];
            let v = nodes.velocities.of_surface_node(nodes.surface, k, x);
            if s.bad.is_none() {
                if !is_finite(x) {
                    s.bad = Some((k, false));
                } else if !is_finite(v) {
                    s.bad = Some((k, true));
                }
            }
            if let Some(r) = nodes.reference {
                s.max_drift2 = s.max_drift2.max(drift2(nodes.expected, x, r[k]));
            }
            s.speed(k, norm2(v));
        }
        s
    }

    fn same(a: Scan, b: Scan) -> bool {
        a.bad == b.bad
            && a.max_drift2.to_bits() == b.max_drift2.to_bits()
            && a.max_speed2.to_bits() == b.max_speed2.to_bits()
            && a.fastest == b.fastest
    }

    #[test]
    fn the_scan_is_the_node_by_node_scan_bit_for_bit() {
        // Three chunks of surface nodes (every other global node), with equal speeds in
        // two chunks so that the first of the fastest is chosen.
        let n = 2 * CHUNK + 37;
        let surface = ContactSurface {
            triangles: Vec::new(),
            triangle_body: Vec::new(),
            surface_nodes: (0..n).map(|k| 2 * k).collect(),
            node_body: (0..n).map(|k| (k / 50) as u32).collect(),
            control_areas: vec![1e-6; n],
        };
        let wave = |i: usize, f: f64| ((i as f64) * f).sin();
        let x: Vec<[f64; 3]> = (0..2 * n)
            .map(|i| [wave(i, 0.7), wave(i, 1.3), wave(i, 2.9)])
            .collect();
        let mut v: Vec<[f64; 3]> = (0..2 * n)
            .map(|i| [wave(i, 0.3), wave(i, 0.5), 0.0])
            .collect();
        v[2 * 10] = [3.0, 0.0, 0.0];
        v[2 * (CHUNK + 5)] = [0.0, 3.0, 0.0];
        let reference: Vec<[f64; 3]> = (0..n).map(|k| x[2 * k].map(|c| c * 0.999 + 1e-3)).collect();
        let rate = [[0.0; 3], [0.0; 3], [0.0, 0.0, -0.5]];
        let motion = MeanMotion::continued(None, [0.0, 0.0, 0.1], rate, 0.0);
        let expected = motion.since(&crate::mean_motion::IDENTITY, 0.01).unwrap();
        let mut cases = vec![(x.clone(), v.clone())];
        for (k, what, value) in [
            (CHUNK + 3, 0, f64::NAN),
            (CHUNK + 3, 1, f64::INFINITY),
            (2 * CHUNK + 1, 0, f64::NEG_INFINITY),
            (4, 1, f64::NAN),
        ] {
            let (mut x, mut v) = (x.clone(), v.clone());
            [&mut x, &mut v][what][2 * k][1] = value;
            // A later bad velocity in the same chunk: the first bad node is named.
            v[2 * (k + 2)][0] = f64::NAN;
            cases.push((x, v));
        }
        for (x, v) in &cases {
            for (reference, expected) in [
                (None, None),
                (Some(reference.as_slice()), None),
                (Some(reference.as_slice()), Some(&expected)),
            ] {
                let nodes = Nodes {
                    surface: &surface,
                    positions: x,
                    velocities: NodeVelocities::new(v, None, 0.0),
                    reference,
                    expected,
                };
                let (got, want) = (nodes.scan(), node_by_node(&nodes));
                assert!(same(got, want), "{got:?} != {want:?}");
            }
        }
        // The cases test what they should: a first bad node, a drift, the first fastest.
        let nodes = |x, v| Nodes {
            surface: &surface,
            positions: x,
            velocities: NodeVelocities::new(v, None, 0.0),
            reference: Some(&reference),
            expected: Some(&expected),
        };
        let clean = nodes(&cases[0].0, &cases[0].1).scan();
        assert!(clean.bad.is_none() && clean.max_drift2 > 0.0 && clean.fastest == 10);
        assert_eq!(
            nodes(&cases[1].0, &cases[1].1).scan().bad,
            Some((CHUNK + 3, false))
        );
        assert_eq!(
            nodes(&cases[2].0, &cases[2].1).scan().bad,
            Some((CHUNK + 3, true))
        );
        assert_eq!(nodes(&cases[4].0, &cases[4].1).scan().bad, Some((4, true)));
    }
}
