//! The contact surface: outward triangles with owner bodies, surface nodes with control
//! areas.

use fdem_mesh::MeshAssembly;
use serde::{Deserialize, Serialize};

use crate::ContactError;
use crate::vec3::{norm, sub};

/// Everything the contact model knows about the geometry of the bodies, apart from the
/// node positions of each step. All node ids are global (indices into the node arrays).
///
/// Invariants checked by [`ContactSurface::validate`]: parallel arrays have equal lengths;
/// surface nodes are unique; every triangle vertex is a surface node of the triangle's
/// body (so the Verlet-skin test, which watches surface nodes, sees every face move);
/// control areas are finite and > 0.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactSurface {
    /// Outward triangles (counter-clockwise seen from outside), global node ids.
    pub triangles: Vec<[usize; 3]>,
    /// Owner body of each triangle (parallel to `triangles`).
    pub triangle_body: Vec<u32>,
    /// Global ids of the surface nodes: the nodes that can touch faces and walls.
    pub surface_nodes: Vec<usize>,
    /// Owner body of each surface node (parallel to `surface_nodes`).
    pub node_body: Vec<u32>,
    /// Control area (m^2) of each surface node (parallel to `surface_nodes`): one third of
    /// the areas of the triangles around it, in the reference configuration. The contact
    /// stiffness `k = p A` (eq 2) uses this fixed area; it is not updated as bodies deform.
    pub control_areas: Vec<f64>,
}

impl ContactSurface {
    /// One more than the largest body id a surface node or face names (0 for an empty
    /// surface): the length of a per-body table.
    pub fn n_bodies(&self) -> usize {
        self.node_body
            .iter()
            .chain(&self.triangle_body)
            .map(|&b| b as usize + 1)
            .max()
            .unwrap_or(0)
    }

    /// The surface of every body of a mesh assembly (triangles, surface nodes and control
    /// areas as placed, node owners from the body ranges).
    ///
    /// # Errors
    /// [`ContactError::InconsistentSurface`] if a surface node lies in no body range.
    pub fn from_assembly(assembly: &MeshAssembly) -> Result<ContactSurface, ContactError> {
        let mut node_body = Vec::with_capacity(assembly.surface_nodes.len());
        for (b, range) in assembly.bodies.iter().enumerate() {
            let body = u32::try_from(b).map_err(|_| ContactError::TooLarge {
                what: "body",
                count: assembly.bodies.len(),
                limit: u32::MAX as usize,
            })?;
            if range.surface_nodes.start != node_body.len() {
                return Err(ContactError::InconsistentSurface {
                    what: format!(
                        "body {b} starts its surface nodes at {} but {} precede it",
                        range.surface_nodes.start,
                        node_body.len()
                    ),
                    fix: "build the assembly with MeshAssembly::push_instance only",
                });
            }
            node_body.extend(std::iter::repeat_n(body, range.surface_nodes.len()));
        }
        let surface = ContactSurface {
            triangles: assembly.triangles.clone(),
            triangle_body: assembly.triangle_body.clone(),
            surface_nodes: assembly.surface_nodes.clone(),
            node_body,
            control_areas: assembly.control_areas.clone(),
        };
        surface.validate(assembly.n_nodes())?;
        Ok(surface)
    }

    /// Appends the surface of body `body`: its outward `triangles` and `surface_nodes`
    /// (global node ids) with their `control_areas` (parallel to `surface_nodes`, m^2).
    /// The invariants are checked by [`ContactSurface::validate`] when a contact model is
    /// built on the surface.
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`] when `control_areas` and `surface_nodes` differ in
    /// length.
    pub fn push_body(
        &mut self,
        body: u32,
        triangles: &[[usize; 3]],
        surface_nodes: &[usize],
        control_areas: &[f64],
    ) -> Result<(), ContactError> {
        if control_areas.len() != surface_nodes.len() {
            return Err(ContactError::LengthMismatch {
                array: "control_areas",
                expected: surface_nodes.len(),
                found: control_areas.len(),
                reason: "one control area per surface node",
            });
        }
        self.triangles.extend_from_slice(triangles);
        self.triangle_body
            .extend(std::iter::repeat_n(body, triangles.len()));
        self.surface_nodes.extend_from_slice(surface_nodes);
        self.node_body
            .extend(std::iter::repeat_n(body, surface_nodes.len()));
        self.control_areas.extend_from_slice(control_areas);
        Ok(())
    }

    /// Number of surface nodes.
    pub fn n_surface_nodes(&self) -> usize {
        self.surface_nodes.len()
    }

    /// Number of triangles.
    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// Checks the invariants listed on the type against `n_nodes` global nodes and returns
    /// the map from global node id to surface-node index (`u32::MAX` for interior nodes).
    ///
    /// # Errors
    /// [`ContactError::LengthMismatch`], [`ContactError::NodeOutOfRange`],
    /// [`ContactError::InconsistentSurface`], [`ContactError::InvalidControlArea`] or
    /// [`ContactError::TooLarge`].
    pub fn validate(&self, n_nodes: usize) -> Result<Vec<u32>, ContactError> {
        self.check_sizes(n_nodes)?;
        let slot = self.surface_slots(n_nodes)?;
        self.check_triangles(&slot)?;
        Ok(slot)
    }

    /// Counts within the index widths and parallel arrays of equal lengths.
    fn check_sizes(&self, n_nodes: usize) -> Result<(), ContactError> {
        let n_surface = self.surface_nodes.len();
        // Keys pack the surface index into 31 bits (see the model's history keys).
        let limit = (1usize << 31) - 1;
        if n_surface > limit {
            return Err(ContactError::TooLarge {
                what: "surface node",
                count: n_surface,
                limit,
            });
        }
        if n_nodes > u32::MAX as usize {
            return Err(ContactError::TooLarge {
                what: "node",
                count: n_nodes,
                limit: u32::MAX as usize,
            });
        }
        if self.triangles.len() > u32::MAX as usize - 1 {
            return Err(ContactError::TooLarge {
                what: "triangle",
                count: self.triangles.len(),
                limit: u32::MAX as usize - 1,
            });
        }
        let same = |array, found: usize, expected: usize, reason| {
            if found == expected {
                Ok(())
            } else {
                Err(ContactError::LengthMismatch {
                    array,
                    expected,
                    found,
                    reason,
                })
            }
        };
        same(
            "triangle_body",
            self.triangle_body.len(),
            self.triangles.len(),
            "one owner per triangle",
        )?;
        same(
            "node_body",
            self.node_body.len(),
            n_surface,
            "one owner per surface node",
        )?;
        same(
            "control_areas",
            self.control_areas.len(),
            n_surface,
            "one control area per surface node",
        )?;
        Ok(())
    }

    /// The map from global node to surface-node index; every surface node listed once,
    /// in range, with a finite positive control area.
    fn surface_slots(&self, n_nodes: usize) -> Result<Vec<u32>, ContactError> {
        let mut slot = vec![u32::MAX; n_nodes];
        for (k, &node) in self.surface_nodes.iter().enumerate() {
            if node >= n_nodes {
                return Err(ContactError::NodeOutOfRange {
                    what: format!("surface node entry {k}"),
                    node,
                    n_nodes,
                });
            }
            if slot[node] != u32::MAX {
                return Err(ContactError::InconsistentSurface {
                    what: format!("node {node} is listed twice among the surface nodes"),
                    fix: "list every surface node once",
                });
            }
            slot[node] = k as u32;
            let area = self.control_areas[k];
            if !(area.is_finite() && area > 0.0) {
                return Err(ContactError::InvalidControlArea {
                    node,
                    body: self.node_body[k],
                    area,
                });
            }
        }
        Ok(slot)
    }

    /// Every triangle vertex a surface node of the triangle's own body.
    fn check_triangles(&self, slot: &[u32]) -> Result<(), ContactError> {
        let n_nodes = slot.len();
        for (t, (tri, &body)) in self.triangles.iter().zip(&self.triangle_body).enumerate() {
            for &node in tri {
                if node >= n_nodes {
                    return Err(ContactError::NodeOutOfRange {
                        what: format!("triangle {t} (body {body})"),
                        node,
                        n_nodes,
                    });
                }
                let k = slot[node];
                if k == u32::MAX {
                    return Err(ContactError::InconsistentSurface {
                        what: format!(
                            "node {node} of triangle {t} (body {body}) is not a surface node"
                        ),
                        fix: "list every triangle vertex among the surface nodes",
                    });
                }
                if self.node_body[k as usize] != body {
                    return Err(ContactError::InconsistentSurface {
                        what: format!(
                            "node {node} of triangle {t} belongs to body {} but the triangle to body {body}",
                            self.node_body[k as usize]
                        ),
                        fix: "bodies must not share nodes; give each triangle its owner's id",
                    });
                }
            }
        }
        Ok(())
    }

    /// Shortest edge (m) of the triangles at the given node positions, `None` without
    /// triangles or with a position index out of range.
    pub fn shortest_edge(&self, positions: &[[f64; 3]]) -> Option<f64> {
        let mut best: Option<f64> = None;
        for tri in &self.triangles {
            for (i, j) in [(0, 1), (1, 2), (2, 0)] {
                let l = norm(sub(*positions.get(tri[i])?, *positions.get(tri[j])?));
                if l.is_finite() && l > 0.0 {
                    best = Some(best.map_or(l, |b: f64| b.min(l)));
                }
            }
        }
        best
    }
}
