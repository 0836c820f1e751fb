//! Bodies: contiguous node and element ranges of one kind, their elements' connectivity,
//! and their rigid-body summaries.

use crate::NodeState;
use fdem_core::geometry::cross;
use std::ops::Range;

/// What a body is, and so which parts of the engine move it.
///
/// Every kind owns a contiguous range of nodes; the engine integrates all nodes alike and
/// each kind differs only in where its forces come from. A new kind (a rigid particle) is
/// one more variant here and one more `add_*` of [`crate::ModelBuilder`], not a special
/// case in the contributions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BodyKind {
    /// A particle meshed with tetrahedra that deform elastically (docs/MODEL.md
    /// section 3): its elements are part of the elastic forces and its outward faces part
    /// of the contact surface.
    Deformable,
    /// A thin sheet (the triaxial membrane): nodes with masses and contact faces, but no
    /// tetrahedra; its in-plane forces come from a force contribution of its own, and the
    /// contact model treats its faces as a sheet (one side, no volume behind them).
    Sheet,
    /// A rigid particle (docs/MODEL.md section 12): the template's surface nodes, placed
    /// from the body's pose every step; six degrees of freedom integrated as a rigid body
    /// ([`crate::RigidState`]), with the mass properties of the solid meshed shape. Its
    /// faces are contact faces like a deformable particle's.
    Rigid,
}

/// The tetrahedra of a model: each element's global node ids (4 for a linear element, 10
/// for a quadratic one in VTK_QUADRATIC_TETRA order), numbered in body order. Each body
/// has one element order; bodies of different orders may sit side by side.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Connectivity {
    nodes: Vec<usize>,
    /// End of each element's ids in `nodes`.
    ends: Vec<usize>,
}

impl Connectivity {
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// True without elements.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// The global node ids of element `e`, or `None` past the last element.
    pub fn element(&self, e: usize) -> Option<&[usize]> {
        let end = *self.ends.get(e)?;
        let start = if e == 0 { 0 } else { self.ends[e - 1] };
        Some(&self.nodes[start..end])
    }

    /// The elements' node ids, element by element.
    pub fn iter(&self) -> impl Iterator<Item = &[usize]> {
        (0..self.len()).filter_map(|e| self.element(e))
    }

    /// All node ids, element after element.
    pub fn flat(&self) -> &[usize] {
        &self.nodes
    }

    /// The node count of each element (4 or 10).
    pub fn node_counts(&self) -> Vec<usize> {
        self.iter().map(<[usize]>::len).collect()
    }

    /// Appends elements of `nodes_per_element` body-local ids each, offset by `first`.
    pub(crate) fn extend(&mut self, local: &[usize], nodes_per_element: usize, first: usize) {
        for element in local.chunks_exact(nodes_per_element) {
            self.nodes.extend(element.iter().map(|&i| i + first));
            self.ends.push(self.nodes.len());
        }
    }
}

/// One body of the simulation: a contiguous node range (and element range for deformable
/// particles).
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// What kind of body this is.
    pub kind: BodyKind,
    /// Global node ids.
    pub nodes: Range<usize>,
    /// Global element ids (empty for bodies without tetrahedra).
    pub elements: Range<usize>,
}

/// Rigid-body summary of one body: what `bodies.csv` reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyMotion {
    /// Total mass (kg).
    pub mass: f64,
    /// Mass-weighted centroid (m).
    pub centroid: [f64; 3],
    /// Linear momentum divided by mass (m/s).
    pub velocity: [f64; 3],
    /// Angular velocity `I^-1 L` about the centroid (rad/s).
    pub angular_velocity: [f64; 3],
    /// Angular momentum `L = sum m r x v` about the centroid (kg m^2/s).
    pub angular_momentum: [f64; 3],
}

impl Body {
    /// True for the bodies that are grains of the granular material (deformable and rigid
    /// particles), false for boundaries such as a membrane.
    pub fn is_particle(&self) -> bool {
        matches!(self.kind, BodyKind::Deformable | BodyKind::Rigid)
    }

    /// Rigid-body summary from the node state: centroid, momentum / mass, angular momentum
    /// about the centroid and the angular velocity that inertia tensor maps it from.
    pub fn motion(&self, state: &NodeState) -> BodyMotion {
        let r = self.nodes.clone();
        let x = &state.positions[r.clone()];
        let v = &state.velocities[r.clone()];
        let m = &state.masses[r];
        let mut mass = 0.0;
        let mut c = [0.0; 3];
        let mut p = [0.0; 3];
        for ((xi, vi), &mi) in x.iter().zip(v).zip(m) {
            mass += mi;
            for k in 0..3 {
                c[k] += mi * xi[k];
                p[k] += mi * vi[k];
            }
        }
        for k in 0..3 {
            c[k] /= mass;
            p[k] /= mass;
        }
        // Angular momentum and inertia tensor about the centroid.
        let mut l = [0.0; 3];
        let mut inertia = [[0.0; 3]; 3];
        for ((xi, vi), &mi) in x.iter().zip(v).zip(m) {
            let d = [xi[0] - c[0], xi[1] - c[1], xi[2] - c[2]];
            let u = [vi[0] - p[0], vi[1] - p[1], vi[2] - p[2]];
            let cr = cross(d, u);
            let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            for a in 0..3 {
                l[a] += mi * cr[a];
                for b in 0..3 {
                    let delta = if a == b { d2 } else { 0.0 };
                    inertia[a][b] += mi * (delta - d[a] * d[b]);
                }
            }
        }
        let angular_velocity = solve3(inertia, l).unwrap_or([0.0; 3]);
        BodyMotion {
            mass,
            centroid: c,
            velocity: p,
            angular_velocity,
            angular_momentum: l,
        }
    }
}

/// Solves the 3x3 system `a x = b` by Cramer's rule; `None` if `a` is singular (or not
/// finite). The system is first divided by its largest entry, so that the determinants
/// (cubes of the entries) neither overflow nor underflow for a body of extreme mass or
/// size: the solution is the same.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let scale = a.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let a = a.map(|row| row.map(|x| x / scale));
    let b = b.map(|x| x / scale);
    let d = det(a);
    if d.is_nan() || d.abs() <= 1e-14 {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut ak = a;
        for row in 0..3 {
            ak[row][k] = b[row];
        }
        *xk = det(ak) / d;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spinning_ring_reports_its_angular_velocity() {
        // Four point masses on a square ring in the xy plane, spinning at w about z.
        let w = 3.0;
        let pos = vec![
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 0.5],
            [0.0, 0.0, -0.5],
        ];
        let mut state = NodeState::new(pos.clone(), vec![1.0; 6]);
        for (v, x) in state.velocities.iter_mut().zip(&pos) {
            let u = cross([0.0, 0.0, w], *x);
            *v = [u[0] + 2.0, u[1], u[2]];
        }
        let body = Body {
            kind: BodyKind::Sheet,
            nodes: 0..6,
            elements: 0..0,
        };
        let m = body.motion(&state);
        assert_eq!(m.mass, 6.0);
        assert!((m.velocity[0] - 2.0).abs() < 1e-14);
        assert!((m.angular_velocity[2] - w).abs() < 1e-12);
        assert!(m.angular_velocity[0].abs() < 1e-12 && m.angular_velocity[1].abs() < 1e-12);
        // The same ring of extreme masses or size: its inertia's determinant would over-
        // or underflow; the angular velocity is the same.
        for (mass, size) in [(1e290, 1.0), (1e-290, 1.0), (1.0, 1e-100), (1.0, 1e100)] {
            let pos: Vec<[f64; 3]> = pos.iter().map(|x| x.map(|c| c * size)).collect();
            let mut state = NodeState::new(pos.clone(), vec![mass; 6]);
            for (v, x) in state.velocities.iter_mut().zip(&pos) {
                *v = cross([0.0, 0.0, w], *x);
            }
            let m = body.motion(&state);
            assert!(
                (m.angular_velocity[2] - w).abs() < 1e-12,
                "{mass:e} kg, {size:e} m: {:?}",
                m.angular_velocity
            );
        }
    }
}
