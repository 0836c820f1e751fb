//! The `auto` particle model: rigid where the particle's own elastic deflection under its
//! expected contact force is a small fraction of the contact overlap (docs/MODEL.md
//! section 12), deformable elsewhere.

use crate::ParticleModel;
use serde::{Deserialize, Serialize};

/// Default threshold of the `auto` model: rigid where the estimated deflection is below
/// this fraction of the overlap. A project choice, to be checked by the study.
pub const DEFAULT_AUTO_THRESHOLD: f64 = 0.05;

/// What the estimate needs for one kind of particle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeflectionInputs {
    /// Nominal diameter `d` (m).
    pub diameter: f64,
    /// Young's modulus `E` of the particle (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio `nu`.
    pub poisson_ratio: f64,
    /// Normal penalty `p_n` (N/m^3, eq 1).
    pub normal_penalty: f64,
    /// Mean control area `A` of one surface node (m^2).
    pub node_area: f64,
    /// Expected normal contact force `f` (N).
    pub contact_force: f64,
}

/// Which regime of contact the estimate found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PatchRegime {
    /// The overlap's lens covers more than one node's control area.
    Lens,
    /// One node carries the force (the lens is smaller than a node's area).
    Node,
}

/// The estimate and the choice it leads to.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeflectionEstimate {
    /// The inputs.
    pub inputs: DeflectionInputs,
    /// Expected contact overlap `delta` (m).
    pub overlap: f64,
    /// Radius `a` of the loaded patch (m).
    pub patch_radius: f64,
    /// Which regime set the patch.
    pub regime: PatchRegime,
    /// The particle's own elastic deflection `w` under `f` (m).
    pub deflection: f64,
    /// `w / delta`.
    pub ratio: f64,
    /// The threshold it was compared with.
    pub threshold: f64,
    /// Rigid if `ratio < threshold`, deformable otherwise.
    pub model: ParticleModel,
}

/// Estimates the particle's elastic deflection against the contact overlap
/// (docs/MODEL.md section 12) and chooses rigid below `threshold`.
///
/// Two spheres of radius `R = d/2` pressed to an overlap `delta` touch over a lens of
/// radius `a^2 = R delta` with depth `delta - rho^2 / R`; eq 1 integrated over it gives
/// `f = p_n pi R delta^2 / 2`. A faceted surface touches at its nodes, so where that lens
/// is smaller than one node's control area `A`, one node carries the force:
/// `delta = f / (p_n A)` over a patch of `a = sqrt(A / pi)`. The particle under the
/// patch deflects as an elastic half-space loaded by a rigid flat punch (Boussinesq):
/// `w = f (1 - nu^2) / (2 a E)`.
pub fn deflection_estimate(inputs: DeflectionInputs, threshold: f64) -> DeflectionEstimate {
    let DeflectionInputs {
        diameter,
        youngs_modulus: e,
        poisson_ratio: nu,
        normal_penalty: p_n,
        node_area,
        contact_force: f,
    } = inputs;
    let pi = std::f64::consts::PI;
    let radius = 0.5 * diameter;
    let lens_overlap = (2.0 * f / (pi * p_n * radius)).sqrt();
    let lens_radius = (radius * lens_overlap).sqrt();
    let node_radius = (node_area / pi).sqrt();
    let (overlap, patch_radius, regime) = if lens_radius >= node_radius {
        (lens_overlap, lens_radius, PatchRegime::Lens)
    } else {
        (f / (p_n * node_area), node_radius, PatchRegime::Node)
    };
    let deflection = f * (1.0 - nu * nu) / (2.0 * patch_radius * e);
    let ratio = deflection / overlap;
    DeflectionEstimate {
        inputs,
        overlap,
        patch_radius,
        regime,
        deflection,
        ratio,
        threshold,
        model: if ratio < threshold {
            ParticleModel::Rigid
        } else {
            ParticleModel::Deformable
        },
    }
}

/// The mean control area (m^2) of a surface node of `template` (a unit-diameter mesh)
/// scaled to `diameter`: the `A` of [`DeflectionInputs::node_area`].
pub fn mean_node_area(template: &fdem_mesh::TetMesh, diameter: f64) -> f64 {
    let surface = &template.surface;
    diameter * diameter * surface.area() / surface.nodes.len().max(1) as f64
}

/// The mean normal contact force (N) in a packing of solid fraction `phi` and
/// coordination `z` under a mean stress `sigma` (Pa), for particles of diameter `d`
/// (m): Love-Weber's `sigma = phi z <f> / (pi d^2)` solved for `<f>`.
pub fn mean_contact_force(sigma: f64, d: f64, phi: f64, z: f64) -> f64 {
    std::f64::consts::PI * d * d * sigma / (phi * z)
}

impl std::fmt::Display for DeflectionEstimate {
    /// One line: the inputs that matter, the estimate, the decision.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let regime = match self.regime {
            PatchRegime::Lens => "lens",
            PatchRegime::Node => "one node",
        };
        write!(
            f,
            "d = {:.4e} m: contact force {:.3e} N, overlap {:.3e} m over a patch of radius {:.3e} m ({regime}), \
             own deflection {:.3e} m = {:.4} of the overlap {} threshold {} -> {}",
            self.inputs.diameter,
            self.inputs.contact_force,
            self.overlap,
            self.patch_radius,
            self.deflection,
            self.ratio,
            if self.ratio < self.threshold {
                "<"
            } else {
                ">="
            },
            self.threshold,
            self.model.name()
        )
    }
}
