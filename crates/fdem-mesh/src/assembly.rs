//! Placing template meshes into global structure-of-arrays.

use std::ops::Range;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::{ElementOrder, MeshError, TetMesh};

/// Tolerance on `| |q| - 1 |` for a placement quaternion.
pub const ROTATION_NORM_TOLERANCE: f64 = 1e-6;

/// Where and how big one instance of a template mesh is: a template point `x` goes to
/// `R(rotation) (scale x) + translation`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    /// Uniform scale factor, finite and > 0 (a template of diameter `d` becomes
    /// `scale * d`).
    pub scale: f64,
    /// Unit quaternion `[w, x, y, z]`. Rejected if a component is not finite or if
    /// `| |q| - 1 | > 1e-6`; accepted quaternions are renormalised before use so the
    /// rotation is orthogonal to round-off.
    pub rotation: [f64; 4],
    /// Translation (m), applied after scaling and rotation.
    pub translation: [f64; 3],
}

impl Default for Placement {
    fn default() -> Self {
        Placement::identity()
    }
}

impl Placement {
    /// Scale 1, no rotation, no translation.
    pub fn identity() -> Placement {
        Placement {
            scale: 1.0,
            rotation: [1.0, 0.0, 0.0, 0.0],
            translation: [0.0; 3],
        }
    }

    /// Scale 1, no rotation, the given translation.
    pub fn at(translation: [f64; 3]) -> Placement {
        Placement {
            translation,
            ..Placement::identity()
        }
    }

    /// Checks the placement and returns the point map `x -> R (scale x) + t`.
    ///
    /// # Errors
    /// [`MeshError::InvalidScale`], [`MeshError::InvalidRotation`] or
    /// [`MeshError::InvalidTranslation`].
    pub fn transform(&self) -> Result<impl Fn([f64; 3]) -> [f64; 3] + use<>, MeshError> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(MeshError::InvalidScale { scale: self.scale });
        }
        let [w, x, y, z] = self.rotation;
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        if !norm.is_finite() || (norm - 1.0).abs() > ROTATION_NORM_TOLERANCE {
            return Err(MeshError::InvalidRotation {
                rotation: self.rotation,
                norm,
            });
        }
        if self.translation.iter().any(|c| !c.is_finite()) {
            return Err(MeshError::InvalidTranslation {
                translation: self.translation,
            });
        }
        let r = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)).to_rotation_matrix();
        let s = self.scale;
        let t = Vector3::from(self.translation);
        Ok(move |p: [f64; 3]| {
            let q = r * (Vector3::from(p) * s) + t;
            [q.x, q.y, q.z]
        })
    }
}

/// Where one body's data sit in the global arrays of a [`MeshAssembly`]. All ranges are
/// half-open and bodies never overlap or share nodes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyRange {
    /// Global node ids of the body.
    pub nodes: Range<usize>,
    /// Global element ids (not positions in the flat array: element `e` occupies
    /// `elements[e * npe .. (e + 1) * npe]`).
    pub elements: Range<usize>,
    /// Indices into [`MeshAssembly::triangles`] / [`MeshAssembly::triangle_body`].
    pub surface_triangles: Range<usize>,
    /// Indices into [`MeshAssembly::surface_nodes`] / [`MeshAssembly::control_areas`].
    pub surface_nodes: Range<usize>,
}

/// Global structure-of-arrays of many placed bodies (see ARCHITECTURE.md "Data layout").
///
/// Every body has the same element order: the first instance fixes [`MeshAssembly::order`]
/// and an instance of the other order is rejected with [`MeshError::MixedOrder`] (a single
/// order keeps the flat element array uniform for the element kernels).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshAssembly {
    /// Element order of all bodies; `None` while the assembly is empty.
    pub order: Option<ElementOrder>,
    /// Node positions (m).
    pub nodes: Vec<[f64; 3]>,
    /// Flat element connectivity with global node ids, `npe` entries per element.
    pub elements: Vec<usize>,
    /// Outward surface triangles with global node ids.
    pub triangles: Vec<[usize; 3]>,
    /// Owner body id of each triangle (parallel to `triangles`).
    pub triangle_body: Vec<u32>,
    /// Global ids of the surface nodes, body after body, sorted within each body.
    pub surface_nodes: Vec<usize>,
    /// Control area (m^2) of each surface node, parallel to `surface_nodes`; scales with
    /// `scale^2` of the placement.
    pub control_areas: Vec<f64>,
    /// Ranges of each body, indexed by body id.
    pub bodies: Vec<BodyRange>,
}

impl MeshAssembly {
    /// An empty assembly.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of bodies.
    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Nodes per element (0 while empty).
    pub fn nodes_per_element(&self) -> usize {
        self.order.map_or(0, ElementOrder::nodes_per_element)
    }

    /// Number of elements.
    pub fn n_elements(&self) -> usize {
        match self.nodes_per_element() {
            0 => 0,
            npe => self.elements.len() / npe,
        }
    }

    /// Global node ids of element `e`, or `None` if there is no such element.
    pub fn element(&self, e: usize) -> Option<&[usize]> {
        let npe = self.nodes_per_element();
        if npe == 0 {
            return None;
        }
        self.elements.get(e * npe..(e + 1) * npe)
    }

    /// Appends one placed copy of `template` as a new body and returns its body id.
    ///
    /// Node positions are mapped by the placement, control areas scaled by `scale^2`, and
    /// every index offset by what the assembly held before. On error nothing is added.
    ///
    /// # Errors
    /// An invalid placement (see [`Placement::transform`]), an inconsistent template
    /// ([`MeshError::InvalidMesh`]), a template of a different element order than the
    /// bodies already present ([`MeshError::MixedOrder`]), or more than `u32::MAX` bodies.
    pub fn push_instance(
        &mut self,
        template: &TetMesh,
        placement: &Placement,
    ) -> Result<usize, MeshError> {
        let map = placement.transform()?;
        template.validate()?;
        if let Some(existing) = self.order
            && existing != template.order
        {
            return Err(MeshError::MixedOrder {
                existing,
                requested: template.order,
            });
        }
        let body = self.bodies.len();
        let body_u32 =
            u32::try_from(body).map_err(|_| MeshError::TooManyBodies { bodies: body })?;

        let node0 = self.nodes.len();
        let element0 = self.n_elements();
        let triangle0 = self.triangles.len();
        let surface0 = self.surface_nodes.len();

        self.order = Some(template.order);
        self.nodes.extend(template.nodes.iter().map(|&p| map(p)));
        self.elements
            .extend(template.elements.iter().map(|&i| i + node0));
        let s = &template.surface;
        self.triangles
            .extend(s.triangles.iter().map(|t| t.map(|i| i + node0)));
        self.triangle_body
            .extend(std::iter::repeat_n(body_u32, s.triangles.len()));
        self.surface_nodes
            .extend(s.nodes.iter().map(|&i| i + node0));
        let area_scale = placement.scale * placement.scale;
        self.control_areas
            .extend(s.control_areas.iter().map(|&a| a * area_scale));

        self.bodies.push(BodyRange {
            nodes: node0..self.nodes.len(),
            elements: element0..self.n_elements(),
            surface_triangles: triangle0..self.triangles.len(),
            surface_nodes: surface0..self.surface_nodes.len(),
        });
        Ok(body)
    }
}
