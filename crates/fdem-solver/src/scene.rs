//! TOML scenes: the public schema of `fdem run`, its validation and the build into a
//! [`Simulation`].
//!
//! The schema is documented in `docs/SCENES.md`; it is a public interface, extended only
//! additively. Every range check happens while deserializing, so an error carries the key
//! path and the line of the offending value.

use crate::SolverError;
use crate::engine::{Guard, Simulation, TimeStep};
use crate::memory::{ModelSize, ParticleSize};
use crate::model::{BodyId, ContactSettings, InitialMotion, ModelBuilder};
use crate::toml_input::{
    Number, axes, check_fraction, check_poisson, check_positive, check_requirement, direction_opt,
    level, poisson, positive, positive_opt, unit_quaternion_opt, vector, vector_opt,
};
use crate::{
    DEFAULT_AUTO_THRESHOLD, DeflectionEstimate, DeflectionInputs, deflection_estimate,
    mean_node_area,
};
use fdem_contact::ContactParams;
use fdem_mesh::{
    ElementOrder, MAX_SHELLS, Placement, Sizing, SphereSpec, TetMesh, sphere_mesh_in_shells,
};
use serde::{Deserialize, Deserializer, Serialize, de::Error as _};
use std::collections::BTreeMap;
use std::path::Path;

/// A whole scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// `[simulation]`: time span, step and outputs.
    pub simulation: SimulationSection,
    /// `[material]`: the particles' elastic material.
    pub material: MaterialSection,
    /// `[[particle]]`: the particles.
    #[serde(rename = "particle", default)]
    pub particles: Vec<ParticleSection>,
    /// `[contact]`: the penalty contact law; default the paper's Table 3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSection>,
    /// `[[wall]]`: rigid walls.
    #[serde(rename = "wall", default, skip_serializing_if = "Vec::is_empty")]
    pub walls: Vec<WallSection>,
    /// `[auto]`: what the `auto` particle model decides from; needed when a particle's
    /// model is `"auto"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto: Option<AutoSection>,
}

/// `[auto]`: the inputs of the `auto` particle model (docs/MODEL.md section 12).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutoSection {
    /// Expected normal contact force on a particle (N), > 0.
    #[serde(deserialize_with = "positive")]
    pub contact_force: f64,
    /// Rigid where the estimated deflection is below this fraction of the overlap;
    /// default [`DEFAULT_AUTO_THRESHOLD`].
    #[serde(default = "default_auto_threshold", deserialize_with = "positive")]
    pub threshold: f64,
}

fn default_auto_threshold() -> f64 {
    DEFAULT_AUTO_THRESHOLD
}

/// `[contact]`: penalty contact (docs/MODEL.md section 2, paper eqs 1-3).
///
/// The law's parameters take their defaults (the paper's Table 3) and their ranges from
/// [`ContactParams`]; the TOML reports a value out of range at its line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    /// Contact on or off; default on.
    #[serde(default = "default_true")]
    pub enabled: bool,
    /// Normal penalty per unit area p_n (N/m^3), > 0.
    #[serde(
        default = "law::normal_penalty::default",
        deserialize_with = "law::normal_penalty::checked"
    )]
    pub normal_penalty: f64,
    /// Tangential / normal penalty ratio, > 0.
    #[serde(
        default = "law::penalty_ratio::default",
        deserialize_with = "law::penalty_ratio::checked"
    )]
    pub penalty_ratio: f64,
    /// Coulomb friction coefficient, >= 0.
    #[serde(
        default = "law::friction::default",
        deserialize_with = "law::friction::checked"
    )]
    pub friction: f64,
    /// Normal damping ratio beta_n, >= 0.
    #[serde(
        default = "law::damping::default",
        deserialize_with = "law::damping::checked"
    )]
    pub damping: f64,
    /// Tangential / normal damping ratio, >= 0.
    #[serde(
        default = "law::damping_ratio::default",
        deserialize_with = "law::damping_ratio::checked"
    )]
    pub damping_ratio: f64,
    /// Contact margin (m): Verlet skin and tunnelling scale against sheets; default a quarter of the
    /// shortest surface edge of the scene.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub margin: Option<f64>,
    /// Depth limit (m): how far behind a face the narrow phase looks; a contact deeper
    /// than half of it stops the run. Default: the margin.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub depth_limit: Option<f64>,
}

/// Serde defaults and range checks of the law's parameters in `[contact]`: each is the
/// field's [`ContactParams::default`] value and [`ContactParams`] range.
mod law {
    macro_rules! parameter {
        ($field:ident, $range:ident) => {
            pub(super) mod $field {
                use fdem_contact::ContactParams;

                pub(in crate::scene) fn default() -> f64 {
                    ContactParams::default().$field
                }

                pub(in crate::scene) fn checked<'de, D: serde::Deserializer<'de>>(
                    d: D,
                ) -> Result<f64, D::Error> {
                    crate::toml_input::meeting(d, ContactParams::$range)
                }
            }
        };
    }
    parameter!(normal_penalty, NORMAL_PENALTY);
    parameter!(penalty_ratio, PENALTY_RATIO);
    parameter!(friction, FRICTION);
    parameter!(damping, DAMPING);
    parameter!(damping_ratio, DAMPING_RATIO);
}

impl Default for ContactSection {
    /// The paper's Table 3 ([`ContactParams::default`]), contact on, margins implicit.
    fn default() -> Self {
        ContactSection::with_law(ContactParams::default())
    }
}

impl ContactSection {
    /// Contact on with the law `law` and implicit margin and depth limit.
    pub fn with_law(law: ContactParams) -> ContactSection {
        ContactSection {
            enabled: true,
            normal_penalty: law.normal_penalty,
            penalty_ratio: law.penalty_ratio,
            friction: law.friction,
            damping: law.damping,
            damping_ratio: law.damping_ratio,
            margin: None,
            depth_limit: None,
        }
    }

    /// The contact law of this section.
    pub fn law(&self) -> ContactParams {
        ContactParams {
            normal_penalty: self.normal_penalty,
            penalty_ratio: self.penalty_ratio,
            friction: self.friction,
            damping: self.damping,
            damping_ratio: self.damping_ratio,
        }
    }

    /// The range checks of deserialization, for a section built in code: the first value
    /// out of range as `(key in the section, message)`.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        for (key, value, requirement) in self.law().fields() {
            check_requirement(requirement, value).map_err(|m| (key, m))?;
        }
        let lengths = [("margin", self.margin), ("depth_limit", self.depth_limit)];
        for (key, value) in lengths {
            if let Some(v) = value {
                check_positive(v).map_err(|m| (key, m))?;
            }
        }
        Ok(())
    }
}

fn default_true() -> bool {
    true
}

/// Shape of a `[[wall]]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WallType {
    /// Infinite plane through `point` with `normal` pointing to the particles' side.
    Plane,
    /// Infinite cylinder (`axis_point`, `axis`, `radius`); particles live inside.
    Cylinder,
}

/// `[[wall]]`: a rigid wall moving at constant velocity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallSection {
    /// `"plane"` or `"cylinder"`.
    #[serde(rename = "type")]
    pub kind: WallType,
    /// Plane: a point on it (m).
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub point: Option<[f64; 3]>,
    /// Plane: normal towards the particles (any length > 0).
    #[serde(
        default,
        deserialize_with = "direction_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub normal: Option<[f64; 3]>,
    /// Cylinder: a point on the axis (m).
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub axis_point: Option<[f64; 3]>,
    /// Cylinder: axis direction (any length > 0).
    #[serde(
        default,
        deserialize_with = "direction_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub axis: Option<[f64; 3]>,
    /// Cylinder: inner radius (m), > 0.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub radius: Option<f64>,
    /// Constant velocity (m/s); default zero.
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity: Option<[f64; 3]>,
}

/// `[simulation]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSection {
    /// Simulated duration (s), required, > 0.
    #[serde(deserialize_with = "positive")]
    pub duration: f64,
    /// Fixed time step (s); omitted means automatic.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub dt: Option<f64>,
    /// Fraction of the stable bound used when `dt` is automatic, in (0, 1]; default 0.5.
    #[serde(
        default,
        deserialize_with = "safety_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub dt_safety: Option<f64>,
    /// Time between outputs (s); default `duration / 100`.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub output_interval: Option<f64>,
    /// Gravitational acceleration (m/s^2); default zero.
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub gravity: Option<[f64; 3]>,
    /// Stability guard: largest energy balance error as a fraction of the energy scale;
    /// default 0.05.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub energy_tolerance: Option<f64>,
    /// Accept particles that start deeper inside one another, or across a wall, than a
    /// contact may reach (half the depth limit); default false: such a start is refused
    /// before the run, naming the bodies.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub allow_initial_overlap: bool,
}

/// `[material]`: isotropic linear elasticity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    /// Density (kg/m^3), > 0.
    #[serde(deserialize_with = "positive")]
    pub density: f64,
    /// Young's modulus (Pa), > 0.
    #[serde(deserialize_with = "positive")]
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5).
    #[serde(deserialize_with = "poisson")]
    pub poisson_ratio: f64,
}

impl MaterialSection {
    /// The range checks of deserialization, for a section built in code: the first value
    /// out of range as `(key in the section, message)`.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        check_positive(self.density).map_err(|m| ("density", m))?;
        check_positive(self.youngs_modulus).map_err(|m| ("youngs_modulus", m))?;
        check_poisson(self.poisson_ratio).map_err(|m| ("poisson_ratio", m))?;
        Ok(())
    }
}

/// `[[particle]]`: one spherical particle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSection {
    /// Nominal diameter (m), > 0.
    #[serde(deserialize_with = "positive")]
    pub diameter: f64,
    /// Centre (m).
    #[serde(deserialize_with = "vector")]
    pub center: [f64; 3],
    /// Initial velocity of the centre (m/s); default zero.
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub velocity: Option<[f64; 3]>,
    /// Initial angular velocity about the centre (rad/s); default zero.
    #[serde(
        default,
        deserialize_with = "vector_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub angular_velocity: Option<[f64; 3]>,
    /// Orientation as a unit quaternion `[w, x, y, z]`; default identity.
    #[serde(
        default,
        deserialize_with = "unit_quaternion_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub orientation: Option<[f64; 4]>,
    /// Mesh of the particle; default level 1, linear, inscribed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshSection>,
    /// How much physics the particle gets: `"deformable"` (default; a tetrahedral mesh
    /// that deforms elastically), `"rigid"` (the mesh's surface moving as one rigid
    /// body with the solid mesh's mass properties; docs/MODEL.md section 12) or `"auto"`
    /// (one of the two, chosen from `[auto]`, [`Scene::resolved_models`]).
    #[serde(default, skip_serializing_if = "ParticleModel::is_default")]
    pub model: ParticleModel,
}

/// The model of one particle ([`ParticleSection::model`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ParticleModel {
    /// Elastic tetrahedra.
    #[default]
    Deformable,
    /// One rigid body.
    Rigid,
    /// Rigid or deformable, chosen from the particle's estimated deflection
    /// ([`crate::deflection_estimate`]); resolved before a model is built.
    Auto,
}

impl ParticleModel {
    /// Whether this is the default model (serde skips writing it).
    pub fn is_default(&self) -> bool {
        *self == ParticleModel::Deformable
    }

    /// The name used in TOML and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ParticleModel::Deformable => "deformable",
            ParticleModel::Rigid => "rigid",
            ParticleModel::Auto => "auto",
        }
    }
}

impl std::str::FromStr for ParticleModel {
    type Err = String;

    /// `"deformable"`, `"rigid"` or `"auto"`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "deformable" => Ok(ParticleModel::Deformable),
            "rigid" => Ok(ParticleModel::Rigid),
            "auto" => Ok(ParticleModel::Auto),
            _ => Err(format!(
                "unknown particle model '{s}'; use \"deformable\", \"rigid\" or \"auto\""
            )),
        }
    }
}

/// `mesh = { level = 1, order = "linear", shells = 1, sizing = "inscribed", axes = [1, 1, 1] }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSection {
    /// Icosahedron subdivision level 0..=4; default 1.
    #[serde(default = "default_level", deserialize_with = "level")]
    pub level: u32,
    /// `"linear"` (4-node) or `"quadratic"` (10-node); default linear.
    #[serde(default = "default_order")]
    pub order: ElementOrder,
    /// Concentric layers of tetrahedra along the radius, `1..=MAX_SHELLS`
    /// ([`sphere_mesh_in_shells`]); default 1, every element touching the centre.
    #[serde(
        default = "default_shells",
        deserialize_with = "shells",
        skip_serializing_if = "is_one_shell"
    )]
    pub shells: u32,
    /// `"inscribed"` or `"volume_equivalent"`; default inscribed.
    #[serde(default)]
    pub sizing: Sizing,
    /// Ellipsoid axes relative to the diameter, `[a, b, c]`: the sphere template
    /// stretched by `a`, `b`, `c` along its own x, y, z ([`TetMesh::stretched`]), before
    /// the particle's orientation turns it; default `[1, 1, 1]`, the sphere.
    #[serde(
        default = "sphere_axes",
        deserialize_with = "axes",
        skip_serializing_if = "is_sphere"
    )]
    pub axes: [f64; 3],
}

impl Default for MeshSection {
    fn default() -> Self {
        MeshSection {
            level: default_level(),
            order: default_order(),
            shells: default_shells(),
            sizing: Sizing::default(),
            axes: sphere_axes(),
        }
    }
}

/// The axes of the sphere, `[1, 1, 1]`.
pub fn sphere_axes() -> [f64; 3] {
    [1.0; 3]
}

fn is_sphere(axes: &[f64; 3]) -> bool {
    *axes == sphere_axes()
}

impl MeshSection {
    /// The unit-diameter template mesh of this section: the icosphere, stretched into an
    /// ellipsoid by `axes`.
    ///
    /// # Errors
    /// What fdem-mesh refuses (a level or shell count out of range, axes that are not
    /// positive).
    pub fn template(&self) -> Result<TetMesh, fdem_mesh::MeshError> {
        let spec = SphereSpec {
            level: self.level,
            order: self.order,
            diameter: 1.0,
            sizing: self.sizing,
        };
        let sphere = sphere_mesh_in_shells(&spec, self.shells)?;
        if is_sphere(&self.axes) {
            Ok(sphere)
        } else {
            sphere.stretched(self.axes)
        }
    }
}

fn default_level() -> u32 {
    1
}

fn default_order() -> ElementOrder {
    ElementOrder::Linear
}

fn default_shells() -> u32 {
    1
}

fn is_one_shell(shells: &u32) -> bool {
    *shells == default_shells()
}

/// `deserialize_with` for the number of shells: an integer in `1..=MAX_SHELLS`.
fn shells<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    let v = i64::deserialize(d)?;
    if (1..=i64::from(MAX_SHELLS)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(D::Error::custom(format!(
            "the number of shells must be an integer from 1 to {MAX_SHELLS}, got {v}"
        )))
    }
}

/// Default fraction of the stable bound.
pub const DEFAULT_DT_SAFETY: f64 = 0.5;
/// Default contact margin as a fraction of the shortest surface edge of the scene.
pub const DEFAULT_MARGIN_FRACTION: f64 = 0.25;
/// Default number of outputs over the duration.
pub const DEFAULT_OUTPUTS: f64 = 100.0;

/// `deserialize_with` for `dt_safety`: a fraction of the stable bound.
fn safety_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    let v = f64::deserialize(d)?;
    check_fraction(v).map(Some).map_err(|_| {
        D::Error::custom(format!(
            "must be a fraction of the stable bound in (0, 1], got {}",
            Number(v)
        ))
    })
}

/// A key name and whether the table has it.
type KeyPresence<'a> = (&'a str, bool);

impl Scene {
    /// Parses a scene from TOML text; `origin` names the file in error messages.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Scene, SolverError> {
        let scene: Scene = crate::toml_input::parse_toml(text, origin)?;
        scene.check_consistency(origin)?;
        Ok(scene)
    }

    /// Reads and parses a scene file.
    pub fn load(path: &Path) -> Result<Scene, SolverError> {
        let text =
            std::fs::read_to_string(path).map_err(|e| SolverError::io("reading scene", path, e))?;
        Scene::from_toml_str(&text, &path.display().to_string())
    }

    /// The scene as TOML text.
    pub fn to_toml_string(&self) -> Result<String, SolverError> {
        toml::to_string(self).map_err(|e| SolverError::InvalidScene(e.to_string()))
    }

    /// Checks that need more than one value.
    fn check_consistency(&self, origin: &str) -> Result<(), SolverError> {
        let fail = |key: String, message: String| SolverError::Scene {
            file: origin.to_string(),
            line: 0,
            column: 0,
            key,
            message,
        };
        if self.particles.is_empty() {
            return Err(fail(
                "particle".into(),
                "the scene has no particles; add at least one [[particle]] table".into(),
            ));
        }
        if self.auto.is_none()
            && let Some(i) = self
                .particles
                .iter()
                .position(|p| p.model == ParticleModel::Auto)
        {
            return Err(fail(
                "auto".into(),
                format!(
                    "particle[{i}] has model = \"auto\", which decides from the expected contact force; \
                     add `[auto]` with `contact_force = ...` (N), or give the particle \"rigid\" or \"deformable\""
                ),
            ));
        }
        for (i, w) in self.walls.iter().enumerate() {
            let (needed, unused): (&[KeyPresence], &[KeyPresence]) = match w.kind {
                WallType::Plane => (
                    &[("point", w.point.is_some()), ("normal", w.normal.is_some())],
                    &[
                        ("axis_point", w.axis_point.is_some()),
                        ("axis", w.axis.is_some()),
                        ("radius", w.radius.is_some()),
                    ],
                ),
                WallType::Cylinder => (
                    &[
                        ("axis_point", w.axis_point.is_some()),
                        ("axis", w.axis.is_some()),
                        ("radius", w.radius.is_some()),
                    ],
                    &[("point", w.point.is_some()), ("normal", w.normal.is_some())],
                ),
            };
            for (key, present) in needed {
                if !present {
                    return Err(fail(
                        format!("wall[{i}].{key}"),
                        format!("a {:?} wall needs `{key}`", w.kind).to_lowercase(),
                    ));
                }
            }
            for (key, present) in unused {
                if *present {
                    return Err(fail(
                        format!("wall[{i}].{key}"),
                        format!("`{key}` does not apply to a {:?} wall; remove it", w.kind)
                            .to_lowercase(),
                    ));
                }
            }
        }
        for (i, p) in self.particles.iter().enumerate() {
            // The meshed volume scales as d^3 a b c: beyond the range of f64 the element
            // volumes, masses and stiffnesses over- or underflow.
            let axes = p.mesh.map_or(sphere_axes(), |m| m.axes);
            let volume =
                std::f64::consts::FRAC_PI_6 * p.diameter.powi(3) * axes[0] * axes[1] * axes[2];
            if !volume.is_normal() {
                return Err(fail(
                    format!("particle[{i}].diameter"),
                    format!(
                        "{} m with mesh.axes [{}, {}, {}] gives a volume of {} m^3, beyond the \
                         range of the arithmetic; use a diameter of a realistic magnitude",
                        Number(p.diameter),
                        Number(axes[0]),
                        Number(axes[1]),
                        Number(axes[2]),
                        Number(volume)
                    ),
                ));
            }
        }
        let s = &self.simulation;
        if let Some(interval) = s.output_interval
            && interval > s.duration
        {
            return Err(fail(
                "simulation.output_interval".into(),
                format!(
                    "{} s is longer than the duration {} s",
                    Number(interval),
                    Number(s.duration)
                ),
            ));
        }
        if let Some(interval) = s.output_interval
            && s.duration / interval > crate::run::MAX_OUTPUTS
        {
            return Err(fail(
                "simulation.output_interval".into(),
                format!(
                    "{interval:e} s gives {:.3e} outputs over {:e} s, more than {:e}; lengthen it",
                    s.duration / interval,
                    s.duration,
                    crate::run::MAX_OUTPUTS
                ),
            ));
        }
        if let Some(dt) = s.dt
            && dt > s.duration
        {
            return Err(fail(
                "simulation.dt".into(),
                format!(
                    "{} s is longer than the duration {} s",
                    Number(dt),
                    Number(s.duration)
                ),
            ));
        }
        Ok(())
    }

    /// The time-step rule of the scene.
    pub fn time_step(&self) -> TimeStep {
        match self.simulation.dt {
            Some(dt) => TimeStep::Fixed(dt),
            None => TimeStep::Automatic {
                safety: self.simulation.dt_safety.unwrap_or(DEFAULT_DT_SAFETY),
            },
        }
    }

    /// Time between outputs (s).
    pub fn output_interval(&self) -> f64 {
        self.simulation
            .output_interval
            .unwrap_or(self.simulation.duration / DEFAULT_OUTPUTS)
    }

    /// The contact parameters in force (the `[contact]` table or the paper's defaults).
    pub fn contact_section(&self) -> ContactSection {
        self.contact.clone().unwrap_or_default()
    }

    /// The contact law of the scene's `[contact]` section (defaults of Table 3 filled in).
    pub fn contact_params(&self) -> ContactParams {
        self.contact_section().law()
    }

    /// The scene's `[[wall]]` tables as contact walls.
    pub fn contact_walls(&self) -> Vec<fdem_contact::Wall> {
        self.walls
            .iter()
            .map(|w| {
                let wall = match w.kind {
                    WallType::Plane => fdem_contact::Wall::plane(
                        w.point.unwrap_or_default(),
                        w.normal.unwrap_or_default(),
                    ),
                    WallType::Cylinder => fdem_contact::Wall::cylinder(
                        w.axis_point.unwrap_or_default(),
                        w.axis.unwrap_or_default(),
                        w.radius.unwrap_or_default(),
                    ),
                };
                wall.moving(w.velocity.unwrap_or([0.0; 3]))
            })
            .collect()
    }

    /// The contact settings of the scene for `model` (the particles already added):
    /// its law, `[contact] margin` or [`DEFAULT_MARGIN_FRACTION`] times the shortest
    /// surface edge of the model so far, and `[contact] depth_limit`.
    ///
    /// # Errors
    /// [`SolverError::InvalidScene`] when the margin is implicit and there is no edge.
    pub fn contact_settings(&self, model: &ModelBuilder) -> Result<ContactSettings, SolverError> {
        let c = self.contact_section();
        let margin = match c.margin {
            Some(m) => m,
            None => model
                .shortest_surface_edge()
                .map(|e| DEFAULT_MARGIN_FRACTION * e)
                .ok_or_else(|| {
                    SolverError::InvalidScene("the scene has no surface edges".into())
                })?,
        };
        Ok(ContactSettings {
            params: self.contact_params(),
            margin,
            depth_limit: c.depth_limit,
            depth_limit_cap: None,
            sheet_fold_depth: None,
        })
    }

    /// The particles' elastic material.
    pub fn elastic_material(&self) -> Result<fdem_elastic::Material, SolverError> {
        let m = &self.material;
        fdem_elastic::Material::new(m.density, m.youngs_modulus, m.poisson_ratio)
            .map_err(|source| SolverError::Elastic { body: 0, source })
    }

    /// Adds the scene's particles to `model` (one unit-diameter template mesh per mesh
    /// kind, scaled, rotated and moved to each particle) and returns their ids.
    pub fn add_particles(&self, model: &mut ModelBuilder) -> Result<Vec<BodyId>, SolverError> {
        let material = self.elastic_material()?;
        let mut templates: BTreeMap<(u32, bool, u32, bool, [u64; 3]), TetMesh> = BTreeMap::new();
        let mut ids = Vec::with_capacity(self.particles.len());
        for p in &self.particles {
            let mesh = p.mesh.unwrap_or_default();
            let key = (
                mesh.level,
                mesh.order == ElementOrder::Quadratic,
                mesh.shells,
                mesh.sizing == Sizing::VolumeEquivalent,
                mesh.axes.map(f64::to_bits),
            );
            let template = match templates.entry(key) {
                std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
                std::collections::btree_map::Entry::Vacant(e) => e.insert(mesh.template()?),
            };
            let placement = Placement {
                scale: p.diameter,
                rotation: p.orientation.unwrap_or([1.0, 0.0, 0.0, 0.0]),
                translation: p.center,
            };
            let motion = InitialMotion {
                velocity: p.velocity.unwrap_or([0.0; 3]),
                angular_velocity: p.angular_velocity.unwrap_or([0.0; 3]),
            };
            let resolved = match p.model {
                ParticleModel::Auto => self.auto_estimate(p.diameter, template)?.model,
                m => m,
            };
            ids.push(match resolved {
                ParticleModel::Rigid => model.add_rigid(template, &placement, &material, motion)?,
                _ => model.add_deformable(template, &placement, &material, motion)?,
            });
        }
        Ok(ids)
    }

    /// The `auto` decision for a particle of `diameter` meshed by the unit-diameter
    /// `template`: its mean surface-node control area, the scene's material and penalty,
    /// and `[auto]`'s force and threshold.
    fn auto_estimate(
        &self,
        diameter: f64,
        template: &TetMesh,
    ) -> Result<DeflectionEstimate, SolverError> {
        let auto = self.auto.ok_or_else(|| {
            SolverError::InvalidScene(
                "a particle has model = \"auto\" but the scene has no [auto] table".into(),
            )
        })?;
        Ok(deflection_estimate(
            DeflectionInputs {
                diameter,
                youngs_modulus: self.material.youngs_modulus,
                poisson_ratio: self.material.poisson_ratio,
                normal_penalty: self.contact_params().normal_penalty,
                node_area: mean_node_area(template, diameter),
                contact_force: auto.contact_force,
            },
            auto.threshold,
        ))
    }

    /// The radius of the ball inside each particle's mesh about its centre (m).
    fn inscribed_radii(&self) -> Result<Vec<f64>, SolverError> {
        let mut known: Vec<(MeshSection, f64)> = Vec::new();
        let mut radii = Vec::with_capacity(self.particles.len());
        for p in &self.particles {
            let mesh = p.mesh.unwrap_or_default();
            let unit = match known.iter().find(|(m, _)| *m == mesh) {
                Some(&(_, r)) => r,
                None => {
                    let r = crate::initial_overlap::inscribed_radius(&mesh.template()?);
                    known.push((mesh, r));
                    r
                }
            };
            radii.push(unit * p.diameter);
        }
        Ok(radii)
    }

    /// The model of every particle, `auto` resolved, with the estimate behind each `auto`
    /// decision.
    ///
    /// # Errors
    /// A mesh that cannot be built.
    pub fn resolved_models(
        &self,
    ) -> Result<Vec<(ParticleModel, Option<DeflectionEstimate>)>, SolverError> {
        self.particles
            .iter()
            .map(|p| match p.model {
                ParticleModel::Auto => {
                    let template = p.mesh.unwrap_or_default().template()?;
                    let e = self.auto_estimate(p.diameter, &template)?;
                    Ok((e.model, Some(e)))
                }
                m => Ok((m, None)),
            })
            .collect()
    }

    /// Whether the scene's model has contact: contact on, and something to touch (a lone
    /// particle with no wall has none).
    fn models_contact(&self) -> bool {
        self.contact_section().enabled && (self.particles.len() >= 2 || !self.walls.is_empty())
    }

    /// The size of the scene's model (nodes, elements, contact nodes), counted from one
    /// template mesh per kind of mesh before anything is allocated. An `auto` particle is
    /// counted as deformable, the larger of its two models.
    ///
    /// # Errors
    /// A mesh that cannot be built.
    pub fn model_size(&self) -> Result<ModelSize, SolverError> {
        let contact = self.models_contact();
        let mut kinds: Vec<((u32, bool, u32), ParticleSize)> = Vec::new();
        let mut size = ModelSize::default();
        for p in &self.particles {
            let mesh = p.mesh.unwrap_or_default();
            let key = (
                mesh.level,
                mesh.order == ElementOrder::Quadratic,
                mesh.shells,
            );
            let particle = match kinds.iter().find(|(k, _)| *k == key) {
                Some(&(_, s)) => s,
                None => {
                    // Sizing and axes move nodes, not their number.
                    let sphere = MeshSection {
                        sizing: Sizing::default(),
                        axes: sphere_axes(),
                        ..mesh
                    };
                    let s = ParticleSize::of(&sphere.template()?);
                    kinds.push((key, s));
                    s
                }
            };
            size.add(&particle, 1, p.model == ParticleModel::Rigid, contact);
        }
        Ok(size)
    }

    /// The scene as a model: particles, then (with contact on and something to touch)
    /// walls and contact, gravity, the step rule and the guard.
    pub fn model(&self) -> Result<ModelBuilder, SolverError> {
        let mut model = ModelBuilder::new();
        self.add_particles(&mut model)?;
        if self.models_contact() {
            let settings = self.contact_settings(&model)?;
            if !self.simulation.allow_initial_overlap {
                let limit = 0.5 * settings.depth_limit.unwrap_or(settings.margin);
                crate::initial_overlap::check(
                    &self.particles,
                    &self.inscribed_radii()?,
                    &self.walls,
                    limit,
                )?;
            }
            for wall in self.contact_walls() {
                model.add_wall(wall);
            }
            model.set_contact(settings);
        }
        model.set_gravity(self.simulation.gravity.unwrap_or([0.0; 3]));
        model.set_time_step(self.time_step());
        let mut guard = Guard::default();
        if let Some(tol) = self.simulation.energy_tolerance {
            guard.energy_tolerance = tol;
        }
        model.set_guard(guard);
        Ok(model)
    }

    /// Builds the meshes, masses and initial state and returns a ready simulation.
    pub fn build(&self) -> Result<Simulation, SolverError> {
        self.model()?.build()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = "[simulation]\nduration = 1.0\n\
        [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\
        [[particle]]\ndiameter = 0.015\ncenter = [0.0, 0.0, 0.0]\n[contact]\n";

    /// A refused `dt_safety` is printed in exponent form, not as 300 digits.
    #[test]
    fn a_refused_safety_factor_is_printed_in_exponent_form() {
        let text = SCENE.replace("duration = 1.0\n", "duration = 1.0\ndt_safety = 1e300\n");
        let e = Scene::from_toml_str(&text, "t").unwrap_err().to_string();
        assert!(
            e.contains("simulation.dt_safety") && e.ends_with("got 1e300"),
            "{e}"
        );
    }

    /// An empty `[contact]` table is the law's default, and each of the law's parameters
    /// is refused by the TOML (at its line) exactly when the law refuses it.
    #[test]
    fn contact_defaults_and_ranges_are_the_laws() {
        let scene = Scene::from_toml_str(SCENE, "t").unwrap();
        assert_eq!(scene.contact, Some(ContactSection::default()));
        assert_eq!(scene.contact_params(), ContactParams::default());
        assert_eq!(ContactSection::default().law(), ContactParams::default());
        let keys = ContactParams::default().fields().map(|(key, _, _)| key);
        for (i, key) in keys.into_iter().enumerate() {
            for value in [-1.0, 0.0, 0.5] {
                let mut section = ContactSection::default();
                let mut visited = 0;
                section.visit_fields("", &mut |f| {
                    if f.key == key {
                        *f.value = value;
                        visited += 1;
                    }
                });
                assert_eq!(visited, 1, "{key}");
                let law = section.law();
                assert_eq!(law.fields()[i].1, value, "{key}");
                let text = format!("{SCENE}{key} = {value:?}\n");
                let parsed = Scene::from_toml_str(&text, "t");
                assert_eq!(parsed.is_ok(), law.validate().is_ok(), "{key} = {value}");
                assert_eq!(section.check().is_ok(), law.validate().is_ok(), "{key}");
                if let Err(SolverError::Scene { key: k, line, .. }) = parsed {
                    assert_eq!((k.as_str(), line), (&*format!("contact.{key}"), 11));
                }
            }
        }
    }

    /// Finite values whose products over- or underflow are refused before the run, each
    /// with a message that names what overflows and prints no NaN: a zero or subnormal
    /// wall normal and an extreme diameter while loading; a Young's modulus whose element
    /// frequencies overflow, a rigid particle whose mass does, an initial energy, node
    /// velocity or force that is not finite while building. A rigid particle of extreme
    /// density, whose momentum squared would overflow, has a finite energy and builds.
    #[test]
    fn values_that_overflow_are_refused_before_the_run_without_a_nan() {
        let two = "[[particle]]\ndiameter = 0.015\ncenter = [0.0152, 0.0, 0.0]\n";
        let wall = "[[wall]]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.0076]\n";
        let loading = [
            (
                format!("{SCENE}{wall}normal = [0.0, -0.0, 0.0]\n"),
                "wall[0].normal",
            ),
            (
                format!("{SCENE}{wall}normal = [5e-324, 0.0, 0.0]\n"),
                "wall[0].normal",
            ),
            (SCENE.replace("0.015", "1e300"), "particle[0].diameter"),
            (SCENE.replace("0.015", "1e-300"), "particle[0].diameter"),
        ];
        for (text, key) in loading {
            let e = Scene::from_toml_str(&text, "t").unwrap_err().to_string();
            assert!(
                e.contains(&format!(": {key}: ")) && !e.contains("NaN"),
                "{e}"
            );
        }
        let rigid = SCENE.replace("[contact]", "model = \"rigid\"\n[contact]");
        let building = [
            (
                SCENE.replace("40.0e9", "1e308"),
                "no finite stable time step",
            ),
            (
                rigid.replace("0.015", "1e100").replace("2650.0", "1e12"),
                "a mass that is not finite",
            ),
            (
                SCENE.replace("[contact]", "velocity = [1e300, 0.0, 0.0]\n[contact]"),
                "the energy of the initial state is not finite (kinetic energy not finite)",
            ),
            (
                format!("{SCENE}{two}model = \"rigid\"\nangular_velocity = [1e308, 0.0, 0.0]\n")
                    .replace("2650.0", "1e12"),
                "the position or velocity of node 43 of body 1",
            ),
            (
                format!("{SCENE}damping_ratio = 1.7e308\ndepth_limit = 1e117\n{two}"),
                "the force on node",
            ),
        ];
        for (text, needle) in building {
            let scene = Scene::from_toml_str(&text, "t").unwrap();
            let e = scene.build().err().expect(needle).to_string();
            assert!(e.contains(needle) && !e.contains("NaN"), "{e}");
        }
        let heavy = format!("{rigid}{two}").replace("2650.0", "1e300");
        let sim = Scene::from_toml_str(&heavy, "t").unwrap().build().unwrap();
        assert!(sim.energy().kinetic.is_finite());
    }
}
