//! Memory estimates made before a model is allocated (docs/PERFORMANCE.md, "Memory"):
//! the rule of a specimen's preparation and of a scene's run, so that what cannot fit is
//! refused with the estimate instead of aborting when an allocation fails.

use fdem_mesh::{ElementOrder, TetMesh};

/// Bytes per node of the node state (positions, reference positions, velocities, forces,
/// mass and inverse mass).
pub const BYTES_PER_NODE: u64 = 112;

/// Bytes per element: the kernel's record, its bound and the connectivity, and the
/// element's copy in the lane kernel's blocks (linear, quadratic).
pub const BYTES_PER_ELEMENT: [u64; 2] = [234, 330];

/// Bytes per surface node for the contact model and the rest of a run (candidates,
/// history, scratch), rounded up from a measured whole-process peak.
pub const BYTES_PER_SURFACE_NODE: u64 = 1024;

/// A run's fixed memory beside its particles (binary, thread stacks, the membrane of a
/// small test).
pub const BYTES_BASE: u64 = 64 << 20;

/// How many times a VTU frame holds its data while it is written: the frame's arrays,
/// the writer's copies, their base64 text and the document; measured (docs/PERFORMANCE.md,
/// "Memory": 760 bytes per linear element against 121 of data) and rounded up.
const FRAME_COPIES: u64 = 7;

/// A VTU frame's memory per node: its data (position, displacement, velocity, body: 80
/// bytes) [`FRAME_COPIES`] times.
const FRAME_BYTES_PER_NODE: u64 = FRAME_COPIES * 80;

/// A VTU frame's memory per cell of `n` nodes: its data (connectivity at 8 bytes a node,
/// offset, type, stress, body: 89 bytes plus the connectivity) [`FRAME_COPIES`] times.
const fn frame_bytes_per_cell(n: u64) -> u64 {
    FRAME_COPIES * (89 + 8 * n)
}

/// A contact snapshot's text per surface node (a node row of about fifteen numbers and
/// its share of the pair rows), rounded up.
const SNAPSHOT_BYTES_PER_SURFACE_NODE: u64 = 512;

/// What one particle of a template mesh adds to a model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParticleSize {
    /// Nodes of the mesh.
    pub nodes: u64,
    /// Tetrahedra of the mesh.
    pub elements: u64,
    /// Surface nodes (the nodes of a rigid particle, the contact nodes of either model).
    pub surface_nodes: u64,
    /// Surface triangles (a rigid particle's cells in a VTU frame).
    pub surface_triangles: u64,
    /// Element order.
    pub quadratic: bool,
}

impl ParticleSize {
    /// The sizes of one instance of `template`.
    pub fn of(template: &TetMesh) -> ParticleSize {
        ParticleSize {
            nodes: template.n_nodes() as u64,
            elements: template.n_elements() as u64,
            surface_nodes: template.surface.nodes.len() as u64,
            surface_triangles: template.surface.triangles.len() as u64,
            quadratic: template.order == ElementOrder::Quadratic,
        }
    }
}

/// What a model holds, counted before it is built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModelSize {
    /// Particles.
    pub particles: u64,
    /// Simulated nodes (a rigid particle's surface nodes).
    pub nodes: u64,
    /// Linear tetrahedra.
    pub linear_elements: u64,
    /// Quadratic tetrahedra.
    pub quadratic_elements: u64,
    /// Surface nodes that take part in contact (none when the model has no contact).
    pub contact_nodes: u64,
    /// Surface triangles of the rigid particles (their cells in a VTU frame).
    pub rigid_triangles: u64,
}

impl ModelSize {
    /// Adds `n` particles of size `p`, deformable or rigid, with or without contact.
    pub fn add(&mut self, p: &ParticleSize, n: u64, rigid: bool, contact: bool) {
        let times = |v: u64| v.saturating_mul(n);
        self.particles = self.particles.saturating_add(n);
        if rigid {
            self.nodes = self.nodes.saturating_add(times(p.surface_nodes));
            self.rigid_triangles = self
                .rigid_triangles
                .saturating_add(times(p.surface_triangles));
        } else {
            self.nodes = self.nodes.saturating_add(times(p.nodes));
            let elements = if p.quadratic {
                &mut self.quadratic_elements
            } else {
                &mut self.linear_elements
            };
            *elements = elements.saturating_add(times(p.elements));
        }
        if contact {
            self.contact_nodes = self.contact_nodes.saturating_add(times(p.surface_nodes));
        }
    }

    /// Elements of both orders.
    pub fn elements(&self) -> u64 {
        self.linear_elements.saturating_add(self.quadratic_elements)
    }

    /// Estimated peak memory of the model and its run (bytes): node state, elements,
    /// contact data per contact node and a fixed base.
    pub fn bytes(&self) -> u64 {
        self.nodes
            .saturating_mul(BYTES_PER_NODE)
            .saturating_add(self.linear_elements.saturating_mul(BYTES_PER_ELEMENT[0]))
            .saturating_add(self.quadratic_elements.saturating_mul(BYTES_PER_ELEMENT[1]))
            .saturating_add(self.contact_nodes.saturating_mul(BYTES_PER_SURFACE_NODE))
            .saturating_add(BYTES_BASE)
    }

    /// Estimated memory of writing one VTU frame of the model (bytes).
    pub fn frame_bytes(&self) -> u64 {
        self.nodes
            .saturating_mul(FRAME_BYTES_PER_NODE)
            .saturating_add(self.linear_elements.saturating_mul(frame_bytes_per_cell(4)))
            .saturating_add(
                self.quadratic_elements
                    .saturating_mul(frame_bytes_per_cell(10)),
            )
            .saturating_add(self.rigid_triangles.saturating_mul(frame_bytes_per_cell(3)))
    }

    /// Estimated memory of one contact snapshot's text (bytes).
    pub fn snapshot_bytes(&self) -> u64 {
        self.contact_nodes
            .saturating_mul(SNAPSHOT_BYTES_PER_SURFACE_NODE)
    }
}

/// A byte count for messages: gigabytes with one decimal from 1 GB, megabytes from 1 MB,
/// bytes below.
pub fn bytes_text(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{bytes} bytes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_preparation_s_figures_and_saturation() {
        let p = ParticleSize {
            nodes: 10,
            elements: 4,
            surface_nodes: 8,
            surface_triangles: 12,
            quadratic: false,
        };
        let mut m = ModelSize::default();
        m.add(&p, 3, false, true);
        m.add(&p, 2, true, false);
        assert_eq!(m.particles, 5);
        assert_eq!(m.nodes, 30 + 16);
        assert_eq!((m.linear_elements, m.quadratic_elements), (12, 0));
        assert_eq!((m.contact_nodes, m.rigid_triangles), (24, 24));
        assert_eq!(m.bytes(), 46 * 112 + 12 * 234 + 24 * 1024 + (64 << 20));
        assert_eq!(m.frame_bytes(), 46 * 560 + 12 * 7 * 121 + 24 * 7 * 113);
        m.add(&p, u64::MAX, false, true);
        assert_eq!(m.bytes(), u64::MAX);
        assert_eq!(bytes_text(12_345_678_901), "12.3 GB");
        assert_eq!(bytes_text(67_108_864), "67 MB");
        assert_eq!(bytes_text(1000), "1000 bytes");
    }
}
