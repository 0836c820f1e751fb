//! Specimen definitions: the schema of a user specimen file, the built-in tests of the
//! paper (Table 4), validation, and the parameters as simulated (coarse graining and
//! exact scaling).

use crate::TriaxialError;
use crate::test_spec::{MembraneSection, TestSection};
use fdem_core::number::Number;
use fdem_mesh::{ElementOrder, Sizing};
use fdem_scaling::ScaleLaw;
use fdem_solver::toml_input::{
    at_least_one, check_at_least_one, check_fraction, check_level, check_non_negative,
    check_positive, check_vector, fraction, fraction_opt, level, non_negative, positive,
    positive_opt, vector,
};
use fdem_solver::{ContactSection, Field, MaterialSection, ParticleModel, Role};
use serde::{Deserialize, Serialize};

/// Tolerance on the sum of the mass fractions.
pub const FRACTION_SUM_TOLERANCE: f64 = 1e-6;
/// Densest packing of equal spheres, `pi / sqrt(18)`: a nominal solid fraction above it
/// cannot be reached by any arrangement of the particles.
pub const DENSEST_PACKING: f64 = 0.740_480_489_693_061;
/// Nominal solid fraction of the paper's specimens, the default (docs/MODEL.md section 7).
pub const DEFAULT_SOLID_FRACTION: f64 = 0.65;
/// Inertial number of the default loading velocity (docs/MODEL.md section 8: quasi-static,
/// `I <= 1e-3`).
pub const DEFAULT_INERTIAL_NUMBER: f64 = 1e-3;

/// One size class of a gradation: a particle diameter and the share of the solid mass.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SizeClass {
    /// Nominal particle diameter of the original (h = 1) material (m), > 0. The simulated
    /// particles are `coarse_graining` times larger.
    #[serde(deserialize_with = "positive")]
    pub size: f64,
    /// Share of the solid mass in this class, in (0, 1]; the shares sum to 1.
    #[serde(deserialize_with = "fraction")]
    pub mass_fraction: f64,
}

/// `[mesh]`: the tetrahedral mesh of every particle (MESHES.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecimenMesh {
    /// Icosahedron subdivision level 0..=4; default 1 (the paper's 80 tetrahedra).
    #[serde(default = "default_level", deserialize_with = "level")]
    pub level: u32,
    /// `"linear"` or `"quadratic"`; default quadratic (the paper's 205 nodes).
    #[serde(default = "default_order")]
    pub order: ElementOrder,
    /// `"inscribed"` (default, the paper's reading) or `"volume_equivalent"`.
    #[serde(default)]
    pub sizing: Sizing,
}

impl Default for SpecimenMesh {
    fn default() -> Self {
        SpecimenMesh {
            level: default_level(),
            order: default_order(),
            sizing: Sizing::Inscribed,
        }
    }
}

/// Largest `preparation.loose_solid_fraction` accepted: the most the placement's
/// relaxation reaches in the paper's specimens (a narrow one such as E4s falls short of
/// it, and its column then grows), and none of them gets much further (docs/SPECIMENS.md,
/// "Preparation: the dynamic method", has the fractions reached).
pub const MAX_LOOSE_SOLID_FRACTION: f64 = 0.5;

/// `[preparation]`: the dynamic method (docs/SPECIMENS.md, "Preparation").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreparationSection {
    /// Nominal solid fraction of the loose random packing the platens start from, in
    /// (0, 0.5]; it sets the height of the loose column (grown while the random
    /// placement does not fit). Default 0.35: a denser start leaves the packing more
    /// stressed at the target height, and 0.35 keeps E4s below its confining pressure
    /// (docs/SPECIMENS.md, "Measured: the loose fraction and the stress left in E4s").
    #[serde(default = "default_loose", deserialize_with = "fraction")]
    pub loose_solid_fraction: f64,
    /// Closing speed of the two platens together (m/s), > 0; each platen moves at half of
    /// it. Default 4.0 (docs/SPECIMENS.md).
    #[serde(default = "default_platen_speed", deserialize_with = "positive")]
    pub platen_speed: f64,
    /// Coulomb friction between particles and with the walls during preparation, >= 0.
    /// Default 0 (frictionless compaction, see docs/SPECIMENS.md).
    #[serde(default, deserialize_with = "non_negative")]
    pub friction: f64,
    /// Fraction of the stable time-step bound used, in (0, 1]. Default 0.4: the bound is
    /// the assembled particle's, which lies above the element bound (docs/VERIFICATION.md,
    /// "Free particles in explicit dynamics", has the ratio), so this keeps the
    /// preparation's step where it was validated, about half the element bound
    /// (docs/SPECIMENS.md).
    #[serde(default = "default_dt_safety", deserialize_with = "fraction")]
    pub dt_safety: f64,
    /// Smallest gap between placed spheres, and between spheres and walls, as a fraction
    /// of the smallest simulated diameter, in (0, 1]. Default 0.02.
    #[serde(default = "default_clearance", deserialize_with = "fraction")]
    pub clearance: f64,
    /// Largest accepted penetration (between particles, and into the walls) at the end,
    /// as a fraction of the smallest simulated diameter, in (0, 1]. Default
    /// [`MAX_OVERLAP_DEFORMABLE`], or [`MAX_OVERLAP_RIGID`] for a specimen with rigid
    /// particles ([`SpecimenSpec::max_overlap`]).
    #[serde(
        default,
        deserialize_with = "fraction_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub max_overlap: Option<f64>,
    /// Settling ends when the unbalanced-force ratio falls to this value, in (0, 1].
    /// Default 0.02.
    #[serde(default = "default_unbalanced", deserialize_with = "fraction")]
    pub unbalanced_force: f64,
    /// Longest settling time after the platens stop (s), > 0. Default
    /// ([`PreparationSection::settle_time_or_default`]): the time the platens take to
    /// close by [`DEFAULT_SETTLE_DIAMETERS`] of the largest simulated diameters.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub settle_time: Option<f64>,
    /// Steps between unbalanced-force checks while settling, >= 1. Default 100.
    #[serde(default = "default_check_interval", deserialize_with = "at_least_one")]
    pub check_interval: u64,
    /// Gravitational acceleration (m/s^2); default zero (it breaks exact scaling).
    #[serde(default, deserialize_with = "vector")]
    pub gravity: [f64; 3],
}

/// The default longest settling time, in the time the platens take to close by this
/// many largest diameters. Settling ends as soon as the unbalanced-force criterion holds,
/// so the cap costs nothing to a packing that settles; it only decides how long one that
/// has not settled is given before its check fails.
pub const DEFAULT_SETTLE_DIAMETERS: f64 = 4.0;

impl PreparationSection {
    /// The longest settling time (s): `settle_time`, or by default the time the platens
    /// take to close by [`DEFAULT_SETTLE_DIAMETERS`] diameters of `d_max`.
    pub fn settle_time_or_default(&self, d_max: f64) -> f64 {
        self.settle_time
            .unwrap_or(DEFAULT_SETTLE_DIAMETERS * d_max / self.platen_speed)
    }
}

impl Default for PreparationSection {
    fn default() -> Self {
        PreparationSection {
            loose_solid_fraction: default_loose(),
            platen_speed: default_platen_speed(),
            friction: 0.0,
            dt_safety: default_dt_safety(),
            clearance: default_clearance(),
            max_overlap: None,
            unbalanced_force: default_unbalanced(),
            settle_time: None,
            check_interval: default_check_interval(),
            gravity: [0.0; 3],
        }
    }
}

/// A specimen: geometry, gradation, material, contact, mesh, test loads and preparation.
///
/// The schema of a specimen file (TOML) is documented in docs/SPECIMENS.md. Every length
/// is in metres, every stress in pascals.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecimenSpec {
    /// A name for reports (a preset's is its test name).
    #[serde(default = "default_name")]
    pub name: String,
    /// Outer specimen diameter (m), > 0; the particles fill the inside of the membrane.
    #[serde(deserialize_with = "positive")]
    pub diameter: f64,
    /// Target specimen height (m), > 0.
    #[serde(deserialize_with = "positive")]
    pub height: f64,
    /// Membrane thickness (m), >= 0 and less than the radius; default 0.002.
    #[serde(default = "default_membrane", deserialize_with = "non_negative")]
    pub membrane_thickness: f64,
    /// Nominal solid fraction (nominal sphere volumes over the inner volume), in (0, 0.74].
    /// Default 0.65 unless `particles` is given.
    #[serde(
        default,
        deserialize_with = "fraction_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub solid_fraction: Option<f64>,
    /// Total particle count instead of a solid fraction (shared by the size classes in
    /// proportion to mass fraction over particle volume).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub particles: Option<u64>,
    /// Coarse-graining factor h > 0: simulated diameters are h times the gradation's.
    /// Default 1.
    #[serde(default = "default_one", deserialize_with = "positive")]
    pub coarse_graining: f64,
    /// Whether material and contact parameters follow exact scaling by h
    /// (`ScaleLaw::exact(h)`: only the penalty changes, by 1/h). Default false.
    #[serde(default)]
    pub exact_scaling: bool,
    /// Confining pressure of the test (Pa), > 0; default 0.8e6 (docs/MODEL.md section 8).
    #[serde(default = "default_confining", deserialize_with = "positive")]
    pub confining_pressure: f64,
    /// Axial loading velocity of the test (m/s), > 0; default from the inertial number
    /// 1e-3 (see [`SpecimenSpec::loading_velocity`]).
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub loading_velocity: Option<f64>,
    /// Seed of the random placement and orientations. Default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Size classes of the original (h = 1) material, at least one.
    pub gradation: Vec<SizeClass>,
    /// `[material]` as in scenes; default rock (2650 kg/m^3, 40 GPa, 0.2).
    #[serde(default = "default_material")]
    pub material: MaterialSection,
    /// `[contact]` as in scenes (the test's law); default the paper's Table 3.
    #[serde(default)]
    pub contact: ContactSection,
    /// `[mesh]`: default level 1 quadratic inscribed (the paper's particle).
    #[serde(default)]
    pub mesh: SpecimenMesh,
    /// Model of the particles: `"deformable"` (default, the paper's FDEM), `"rigid"`
    /// (the mesh's surface moving as one rigid body with the solid mesh's mass
    /// properties; docs/MODEL.md section 12) or `"auto"` (per size class, rigid where the
    /// estimated deflection is below `auto_threshold` of the overlap; [`Counts`]).
    ///
    /// [`Counts`]: crate::Counts
    #[serde(default, skip_serializing_if = "ParticleModel::is_default")]
    pub model: ParticleModel,
    /// Threshold of the `auto` model, > 0; default [`fdem_solver::DEFAULT_AUTO_THRESHOLD`].
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub auto_threshold: Option<f64>,
    /// `[preparation]`: the dynamic method's settings.
    #[serde(default)]
    pub preparation: PreparationSection,
    /// `[membrane]`: the test's membrane (material and resolution).
    #[serde(default)]
    pub membrane: MembraneSection,
    /// `[test]`: consolidation, shear and outputs of the triaxial test.
    #[serde(default)]
    pub test: TestSection,
}

/// One built-in test of the paper (Table 4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// Test name (`E1` ... `B3s`).
    pub name: &'static str,
    /// `true` for the binary series (15 and 30 mm originals, equal mass).
    pub binary: bool,
    /// Coarse-graining factor h.
    pub coarse_graining: f64,
    /// Whether exact scaling is applied.
    pub exact_scaling: bool,
}

/// The element order of a specimen's particles in `model` when none is asked for: linear
/// surfaces for rigid and `auto` particles (a rigid particle uses only its surface, and
/// the level-1 linear surface has 42 contact nodes against 162 for the quadratic one; an
/// `auto` class left deformable is then a linear tetrahedral mesh), `own` (the specimen's
/// order) for deformable ones.
pub fn surface_order(model: ParticleModel, own: ElementOrder) -> ElementOrder {
    match model {
        ParticleModel::Deformable => own,
        ParticleModel::Rigid | ParticleModel::Auto => ElementOrder::Linear,
    }
}

const fn preset(name: &'static str, binary: bool, h: f64, exact: bool) -> Preset {
    Preset {
        name,
        binary,
        coarse_graining: h,
        exact_scaling: exact,
    }
}

/// The twelve tests of the paper (Table 4), in its order.
pub const PRESETS: &[Preset] = &[
    preset("E1", false, 1.0, false),
    preset("E2", false, 2.0, false),
    preset("E3", false, 3.0, false),
    preset("E4", false, 4.0, false),
    preset("E2s", false, 2.0, true),
    preset("E3s", false, 3.0, true),
    preset("E4s", false, 4.0, true),
    preset("B1", true, 1.0, false),
    preset("B2", true, 1.5, false),
    preset("B3", true, 2.0, false),
    preset("B2s", true, 1.5, true),
    preset("B3s", true, 2.0, true),
];

/// Largest simulated particle diameter of both paper series (m): 60 mm in E4/E4s and in
/// B3/B3s. The presets' loading velocity keeps these coarsest members at the inertial
/// number 1e-3, so every test of a series shares one velocity (docs/MODEL.md section 5).
pub const SERIES_SIZE: f64 = 0.060;

/// Diameter of the original particles of both series (m): 15 mm, and 30 mm for the
/// coarse half of the binary series.
pub const ORIGINAL_SIZE: f64 = 0.015;

impl Preset {
    /// Looks a test up by name (case-sensitive, as printed in the paper).
    pub fn find(name: &str) -> Result<&'static Preset, TriaxialError> {
        PRESETS
            .iter()
            .find(|p| p.name == name)
            .ok_or_else(|| TriaxialError::UnknownTest {
                name: name.to_string(),
                known: PRESETS
                    .iter()
                    .map(|p| p.name)
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The specimen of this test in `model` with element `order`: [`Preset::spec`] with
    /// the model set and, without an order, [`surface_order`]'s choice for the model.
    pub fn spec_in(&self, model: ParticleModel, order: Option<ElementOrder>) -> SpecimenSpec {
        let mut spec = self.spec();
        spec.model = model;
        spec.mesh.order = order.unwrap_or_else(|| surface_order(model, spec.mesh.order));
        spec
    }

    /// The specimen of this test: phi 300 x 600 mm, 2 mm membrane, nominal solid fraction
    /// 0.65, Table 3 parameters, level-1 quadratic inscribed meshes, default preparation.
    pub fn spec(&self) -> SpecimenSpec {
        let gradation = if self.binary {
            vec![
                SizeClass {
                    size: ORIGINAL_SIZE,
                    mass_fraction: 0.5,
                },
                SizeClass {
                    size: 2.0 * ORIGINAL_SIZE,
                    mass_fraction: 0.5,
                },
            ]
        } else {
            vec![SizeClass {
                size: ORIGINAL_SIZE,
                mass_fraction: 1.0,
            }]
        };
        SpecimenSpec {
            name: self.name.to_string(),
            diameter: 0.300,
            height: 0.600,
            membrane_thickness: default_membrane(),
            solid_fraction: Some(DEFAULT_SOLID_FRACTION),
            particles: None,
            coarse_graining: self.coarse_graining,
            exact_scaling: self.exact_scaling,
            confining_pressure: default_confining(),
            loading_velocity: None,
            seed: default_seed(),
            gradation,
            material: default_material(),
            contact: ContactSection::default(),
            mesh: SpecimenMesh::default(),
            model: ParticleModel::default(),
            auto_threshold: None,
            preparation: PreparationSection::default(),
            membrane: MembraneSection::default(),
            test: TestSection {
                series_size: Some(SERIES_SIZE),
                ..TestSection::default()
            },
        }
    }
}

fn default_name() -> String {
    "specimen".into()
}
fn default_one() -> f64 {
    1.0
}
fn default_membrane() -> f64 {
    0.002
}
fn default_confining() -> f64 {
    0.8e6
}
fn default_seed() -> u64 {
    1
}
fn default_level() -> u32 {
    1
}
fn default_order() -> ElementOrder {
    ElementOrder::Quadratic
}
fn default_loose() -> f64 {
    0.35
}
fn default_platen_speed() -> f64 {
    4.0
}
fn default_dt_safety() -> f64 {
    0.4
}
fn default_clearance() -> f64 {
    0.02
}
/// Default `preparation.max_overlap` of deformable specimens.
pub const MAX_OVERLAP_DEFORMABLE: f64 = 0.02;
/// Default `preparation.max_overlap` of specimens with rigid particles: a rigid faceted
/// particle resting on a platen bears on one vertex or edge, whose nodes carry all its
/// load and press deeper than a deformable particle's flattened contact
/// (docs/SPECIMENS.md, "Rigid specimens", has the measurement).
pub const MAX_OVERLAP_RIGID: f64 = 0.04;
fn default_unbalanced() -> f64 {
    0.02
}
fn default_check_interval() -> u64 {
    100
}

/// Rock (docs/MODEL.md section 8): 2650 kg/m^3, E = 40 GPa, nu = 0.2.
pub fn default_material() -> MaterialSection {
    MaterialSection {
        density: 2650.0,
        youngs_modulus: 40.0e9,
        poisson_ratio: 0.2,
    }
}

/// The parameters of a specimen as simulated: particle sizes times h, and (with exact
/// scaling) material and contact parameters times their `ScaleLaw::exact(h)` factors.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulated {
    /// Simulated diameter of each size class (m), in the order of the gradation.
    pub sizes: Vec<f64>,
    /// Material.
    pub material: MaterialSection,
    /// Contact law of the test.
    pub contact: ContactSection,
    /// Friction during preparation.
    pub preparation_friction: f64,
    /// Every parameter changed by exact scaling: `(key, quantity, factor)`.
    pub scaled: Vec<(String, &'static str, f64)>,
}

impl SpecimenSpec {
    /// The preparation's `max_overlap`: the given one, else the default of the specimen's
    /// model ([`MAX_OVERLAP_RIGID`] when any particle is rigid, [`MAX_OVERLAP_DEFORMABLE`]
    /// otherwise).
    pub fn max_overlap(&self) -> f64 {
        let rigid = self.counts().is_ok_and(|c| c.rigid_particles > 0);
        self.preparation.max_overlap.unwrap_or(if rigid {
            MAX_OVERLAP_RIGID
        } else {
            MAX_OVERLAP_DEFORMABLE
        })
    }
}

impl SpecimenSpec {
    /// Parses a specimen from TOML text and validates it; `origin` names the file in
    /// error messages (`file:line:column: key: message`).
    pub fn from_toml_str(text: &str, origin: &str) -> Result<SpecimenSpec, TriaxialError> {
        let spec: SpecimenSpec =
            fdem_solver::toml_input::parse_toml(text, origin).map_err(|e| {
                TriaxialError::Definition {
                    origin: e.file,
                    line: e.line,
                    column: e.column,
                    key: e.key,
                    message: e.message,
                }
            })?;
        spec.validate(origin)?;
        Ok(spec)
    }

    /// Reads, parses and validates a specimen file.
    pub fn load(path: &std::path::Path) -> Result<SpecimenSpec, TriaxialError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| TriaxialError::io("reading specimen definition", path, e))?;
        SpecimenSpec::from_toml_str(&text, &path.display().to_string())
    }

    /// The specimen as TOML text (the schema of [`SpecimenSpec::from_toml_str`]).
    pub fn to_toml_string(&self) -> Result<String, TriaxialError> {
        toml::to_string(self).map_err(|e| TriaxialError::Definition {
            origin: self.name.clone(),
            line: 0,
            column: 0,
            key: "<document>".into(),
            message: format!("cannot be written as TOML: {e}"),
        })
    }

    /// Inner radius: the outer radius minus the membrane (m).
    pub fn inner_radius(&self) -> f64 {
        0.5 * self.diameter - self.membrane_thickness
    }

    /// Inner cross-section `pi r^2` (m^2).
    pub fn inner_area(&self) -> f64 {
        let r = self.inner_radius();
        std::f64::consts::PI * r * r
    }

    /// Volume inside the membrane at the target height (m^3).
    pub fn inner_volume(&self) -> f64 {
        self.inner_area() * self.height
    }

    /// The nominal solid fraction asked for (0.65 when neither it nor `particles` is given).
    pub fn requested_solid_fraction(&self) -> Option<f64> {
        match (self.solid_fraction, self.particles) {
            (Some(f), _) => Some(f),
            (None, None) => Some(DEFAULT_SOLID_FRACTION),
            (None, Some(_)) => None,
        }
    }

    /// The axial loading velocity of the test (m/s): the given one, or the one at which
    /// the inertial number `I = eps_rate d sqrt(rho / p)` equals `test.inertial_number`
    /// (1e-3) with `d = test.series_size` (default: this specimen's largest simulated
    /// diameter), `rho` the density and `p` the confining pressure:
    /// `v = I H / (d sqrt(rho / p))`. Coarse graining keeps the domain, loads and velocity,
    /// so every member of a series given the same `series_size` shares this velocity and
    /// the coarsest member has the inertial number asked for.
    pub fn loading_velocity(&self) -> f64 {
        self.loading_velocity.unwrap_or_else(|| {
            let d = self
                .test
                .series_size
                .unwrap_or_else(|| self.largest_simulated_size());
            let root = (self.material.density / self.confining_pressure).sqrt();
            self.test.inertial_number * self.height / (d * root)
        })
    }

    /// The largest simulated particle diameter (m): h times the largest gradation size.
    pub fn largest_simulated_size(&self) -> f64 {
        self.coarse_graining * self.gradation.iter().map(|c| c.size).fold(0.0, f64::max)
    }

    /// The smallest simulated particle diameter (m).
    pub fn smallest_simulated_size(&self) -> f64 {
        self.coarse_graining
            * self
                .gradation
                .iter()
                .map(|c| c.size)
                .fold(f64::INFINITY, f64::min)
    }

    /// The inertial number of the test with this specimen's own largest simulated size:
    /// `I = (v / H) d_max sqrt(rho / sigma_0)` (density as simulated: exact scaling keeps
    /// it).
    pub fn inertial_number(&self) -> f64 {
        let root = (self.material.density / self.confining_pressure).sqrt();
        self.loading_velocity() / self.height * self.largest_simulated_size() * root
    }

    /// The parameters as simulated (sizes x h; with exact scaling, every material and
    /// contact parameter times its factor from `ScaleLaw::exact(h)`; the contact margin,
    /// a particle length, always x h).
    ///
    /// The fields and their quantities are the ones the sections declare for scenes
    /// (`visit_fields`), scaled by the rule of scene coarse graining
    /// ([`Role::coarse_graining_factor`]); the specimen adds its own two: the gradation's
    /// sizes (particle lengths) and the preparation friction (a parameter).
    pub fn simulated(&self) -> Result<Simulated, TriaxialError> {
        let law = ScaleLaw::exact(self.coarse_graining)
            .map_err(|e| self.rule("coarse_graining", e.to_string()))?;
        let mut sizes: Vec<f64> = self.gradation.iter().map(|c| c.size).collect();
        let mut material = self.material.clone();
        let mut contact = self.contact.clone();
        let mut preparation_friction = self.preparation.friction;
        let mut scaled = Vec::new();
        let mut apply = |f: Field<'_>| {
            let factor = f
                .role
                .coarse_graining_factor(&law, f.dimension, self.exact_scaling);
            if factor != 1.0 {
                *f.value *= factor;
                if f.role == Role::Parameter {
                    scaled.push((f.key, f.quantity, factor));
                }
            }
        };
        for (i, size) in sizes.iter_mut().enumerate() {
            let key = format!("gradation[{i}].size");
            apply(Field::new(key, "length", Role::Particle, size));
        }
        material.visit_fields("material.", &mut apply);
        contact.visit_fields("contact.", &mut apply);
        let key = "preparation.friction".to_string();
        apply(Field::new(
            key,
            "friction",
            Role::Parameter,
            &mut preparation_friction,
        ));
        Ok(Simulated {
            sizes,
            material,
            contact,
            preparation_friction,
            scaled,
        })
    }

    fn rule(&self, key: &str, message: String) -> TriaxialError {
        definition_error(&self.name, key, message)
    }

    /// Checks every rule of the schema (single values and the rules across keys) before
    /// any work; the first broken rule is returned as one line naming the key.
    pub fn validate(&self, origin: &str) -> Result<(), TriaxialError> {
        self.first_broken_rule()
            .map_err(|(key, message)| definition_error(origin, &key, message))
    }

    /// The steps of [`SpecimenSpec::validate`], in order.
    fn first_broken_rule(&self) -> Result<(), Broken> {
        self.check_values()?;
        self.test.check().map_err(within(""))?;
        self.material.check().map_err(within("material."))?;
        self.check_contact()?;
        single("mesh.level", check_level(i64::from(self.mesh.level)))?;
        self.check_preparation()?;
        self.check_geometry()?;
        self.check_gradation()?;
        self.check_amount_of_solid()?;
        self.simulated()
            .map_err(|e| ("coarse_graining".into(), e.to_string()))?;
        Ok(())
    }
}

/// A broken rule of a definition: `(key, message)`.
type Broken = (String, String);

/// A definition error of `origin` without a line (a rule checked after parsing).
fn definition_error(origin: &str, key: &str, message: String) -> TriaxialError {
    TriaxialError::Definition {
        origin: origin.to_string(),
        line: 0,
        column: 0,
        key: key.to_string(),
        message,
    }
}

/// The result of a single-value check as a broken rule of `key`.
fn single<T>(key: &str, checked: Result<T, String>) -> Result<(), Broken> {
    checked.map(|_| ()).map_err(|m| (key.to_string(), m))
}

/// Prefixes the key of a section's broken rule with the section's path.
fn within(prefix: &str) -> impl Fn((&'static str, String)) -> Broken + '_ {
    move |(key, m)| (format!("{prefix}{key}"), m)
}

/// The steps of [`SpecimenSpec::validate`]; each returns its first broken rule.
impl SpecimenSpec {
    /// The top-level single values.
    fn check_values(&self) -> Result<(), Broken> {
        single("diameter", check_positive(self.diameter))?;
        single("height", check_positive(self.height))?;
        single(
            "membrane_thickness",
            check_non_negative(self.membrane_thickness),
        )?;
        single("coarse_graining", check_positive(self.coarse_graining))?;
        single(
            "confining_pressure",
            check_positive(self.confining_pressure),
        )?;
        if let Some(v) = self.loading_velocity {
            single("loading_velocity", check_positive(v))?;
        }
        Ok(())
    }

    /// `[contact]`: the ranges of the scene schema, and contact switched on.
    fn check_contact(&self) -> Result<(), Broken> {
        self.contact.check().map_err(within("contact."))?;
        if !self.contact.enabled {
            return Err((
                "contact.enabled".into(),
                "a specimen needs contact; remove `enabled = false`".into(),
            ));
        }
        Ok(())
    }

    /// `[preparation]`: single values, then the loose fraction's own range.
    fn check_preparation(&self) -> Result<(), Broken> {
        let p = &self.preparation;
        single("preparation.platen_speed", check_positive(p.platen_speed))?;
        single("preparation.friction", check_non_negative(p.friction))?;
        single("preparation.dt_safety", check_fraction(p.dt_safety))?;
        single("preparation.clearance", check_fraction(p.clearance))?;
        if let Some(m) = p.max_overlap {
            single("preparation.max_overlap", check_fraction(m))?;
        }
        single(
            "preparation.unbalanced_force",
            check_fraction(p.unbalanced_force),
        )?;
        if let Some(t) = p.settle_time {
            single("preparation.settle_time", check_positive(t))?;
        }
        single(
            "preparation.check_interval",
            check_at_least_one(p.check_interval),
        )?;
        single("preparation.gravity", check_vector(p.gravity))?;
        let loose = p.loose_solid_fraction;
        if !(loose > 0.0 && loose <= MAX_LOOSE_SOLID_FRACTION) {
            return Err((
                "preparation.loose_solid_fraction".into(),
                format!(
                    "must lie in (0, {MAX_LOOSE_SOLID_FRACTION}] (the random placement's \
                     relaxation jams near 0.5-0.55), got {}",
                    Number(loose)
                ),
            ));
        }
        Ok(())
    }

    /// Room inside the membrane.
    fn check_geometry(&self) -> Result<(), Broken> {
        if self.inner_radius() <= 0.0 {
            return Err((
                "membrane_thickness".into(),
                format!(
                    "{} m leaves no room inside a specimen of diameter {} m; it must be less than the radius",
                    Number(self.membrane_thickness),
                    Number(self.diameter)
                ),
            ));
        }
        Ok(())
    }

    /// Size classes: present, valid, smaller than the specimen, distinct, fractions
    /// summing to 1.
    fn check_gradation(&self) -> Result<(), Broken> {
        if self.gradation.is_empty() {
            return Err((
                "gradation".into(),
                "no size classes; give at least one { size = ..., mass_fraction = ... }".into(),
            ));
        }
        let h = self.coarse_graining;
        let r = self.inner_radius();
        for (i, class) in self.gradation.iter().enumerate() {
            let size_key = format!("gradation[{i}].size");
            single(&size_key, check_positive(class.size))?;
            single(
                &format!("gradation[{i}].mass_fraction"),
                check_fraction(class.mass_fraction),
            )?;
            let d = class.size * h;
            let limit = (2.0 * r).min(self.height);
            if d >= limit {
                return Err((
                    size_key,
                    format!(
                        "particles of {} m (x coarse_graining {} = {} m) are larger than the specimen \
                         (inner diameter {} m, height {} m); use smaller sizes or a smaller coarse_graining",
                        Number(class.size),
                        Number(h),
                        Number(d),
                        Number(2.0 * r),
                        Number(self.height)
                    ),
                ));
            }
            if self.gradation[..i].iter().any(|o| o.size == class.size) {
                return Err((
                    size_key,
                    format!(
                        "size {} m is listed twice; merge the two classes",
                        Number(class.size)
                    ),
                ));
            }
        }
        let sum: f64 = self.gradation.iter().map(|c| c.mass_fraction).sum();
        if (sum - 1.0).abs() > FRACTION_SUM_TOLERANCE {
            return Err((
                "gradation".into(),
                format!(
                    "mass fractions sum to {}, not 1 (tolerance {FRACTION_SUM_TOLERANCE}); fix the mass_fraction values",
                    (sum * 1e9).round() / 1e9
                ),
            ));
        }
        Ok(())
    }

    /// Amount of solid: one way of giving it, reachable, and denser than the loose
    /// packing the preparation starts from.
    fn check_amount_of_solid(&self) -> Result<(), Broken> {
        match (self.solid_fraction, self.particles) {
            (Some(_), Some(_)) => {
                return Err((
                    "particles".into(),
                    "give either solid_fraction or particles, not both".into(),
                ));
            }
            (Some(f), None) if f > DENSEST_PACKING => {
                return Err((
                    "solid_fraction".into(),
                    format!(
                        "{} exceeds the densest packing of spheres (pi / sqrt(18) = \
                         {DENSEST_PACKING}); no arrangement reaches it",
                        Number(f)
                    ),
                ));
            }
            (None, Some(n)) => single("particles", check_at_least_one(n))?,
            _ => {}
        }
        let loose = self.preparation.loose_solid_fraction;
        let too_loose = |target: String| {
            Err((
                "preparation.loose_solid_fraction".into(),
                format!(
                    "{} must be below {target}, or there is nothing to compact",
                    Number(loose)
                ),
            ))
        };
        if let Some(f) = self.requested_solid_fraction()
            && f <= loose
        {
            return too_loose(format!("the target solid fraction {}", Number(f)));
        }
        let h = self.coarse_graining;
        let counts = crate::counts::class_counts(self)?;
        let solids: f64 = counts
            .iter()
            .zip(&self.gradation)
            .map(|(&n, c)| n as f64 * crate::counts::sphere_volume(c.size * h))
            .sum();
        let implied = solids / self.inner_volume();
        if implied > DENSEST_PACKING {
            let needed = solids / (DENSEST_PACKING * self.inner_area());
            return Err((
                "height".into(),
                format!(
                    "{} m is below the {:.6} m the solids need at the densest packing \
                     ({DENSEST_PACKING}); raise the height or lower the particle count",
                    Number(self.height),
                    Number(needed)
                ),
            ));
        }
        if implied <= loose {
            return too_loose(format!(
                "the specimen's solid fraction {:.4}",
                Number(implied)
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A preset in the rigid or auto model gets linear surfaces unless an order is given;
    /// deformable particles keep the preset's quadratic elements.
    #[test]
    fn a_preset_s_order_follows_its_model_unless_given() {
        let b2 = Preset::find("B2").unwrap();
        assert_eq!(b2.spec().mesh.order, ElementOrder::Quadratic);
        for (model, order, expected) in [
            (ParticleModel::Deformable, None, ElementOrder::Quadratic),
            (ParticleModel::Rigid, None, ElementOrder::Linear),
            (ParticleModel::Auto, None, ElementOrder::Linear),
            (
                ParticleModel::Rigid,
                Some(ElementOrder::Quadratic),
                ElementOrder::Quadratic,
            ),
            (
                ParticleModel::Deformable,
                Some(ElementOrder::Linear),
                ElementOrder::Linear,
            ),
        ] {
            let spec = b2.spec_in(model, order);
            assert_eq!(spec.model, model);
            assert_eq!(spec.mesh.order, expected, "{model:?} {order:?}");
        }
    }

    /// Definitions built in code get the rules of the schema, with the key and the
    /// message of the TOML reader where it has one.
    #[test]
    fn definitions_built_in_code_are_checked_by_the_schema_s_rules() {
        let good = Preset::find("E4").unwrap().spec();
        assert!(good.validate("code").is_ok());
        type Spoil = fn(&mut SpecimenSpec);
        let cases: [(&str, Spoil, &str); 8] = [
            ("diameter", |s| s.diameter = -1.0, "positive finite number"),
            (
                "material.poisson_ratio",
                |s| s.material.poisson_ratio = 0.5,
                "must lie in (-1, 0.5), got 0.5",
            ),
            (
                "contact.penalty_ratio",
                |s| s.contact.penalty_ratio = 0.0,
                "positive finite number",
            ),
            ("contact.damping", |s| s.contact.damping = -0.1, ">= 0"),
            (
                "mesh.level",
                |s| s.mesh.level = 7,
                "subdivision level must be 0, 1, 2, 3 or 4, got 7",
            ),
            (
                "preparation.check_interval",
                |s| s.preparation.check_interval = 0,
                "must be at least 1",
            ),
            (
                "preparation.gravity",
                |s| s.preparation.gravity[2] = f64::NAN,
                "every component must be finite",
            ),
            (
                "particles",
                |s| {
                    s.solid_fraction = None;
                    s.particles = Some(0);
                },
                "must be at least 1",
            ),
        ];
        for (key, spoil, fragment) in cases {
            let mut spec = good.clone();
            spoil(&mut spec);
            let e = spec.validate("code").unwrap_err().to_string();
            assert!(e.starts_with(&format!("code: {key}: ")), "{key}: {e}");
            assert!(e.contains(fragment), "{key}: {e}");
        }
    }

    /// A fraction just above the densest packing is refused with a limit printed to
    /// enough digits to see that it lies above (0.7405 > 0.74048...).
    #[test]
    fn a_fraction_above_the_densest_packing_is_refused_with_the_exact_limit() {
        let mut spec = crate::quick_spec();
        spec.solid_fraction = Some(0.7405);
        let e = spec.validate("code").unwrap_err().to_string();
        assert!(e.contains("0.7405 exceeds") && e.contains("0.74048"), "{e}");
        spec.solid_fraction = Some(DENSEST_PACKING);
        let e = spec.validate("code").map_err(|e| e.to_string());
        assert!(
            e.as_ref().map_or_else(|m| !m.contains("exceeds"), |_| true),
            "{e:?}"
        );
    }

    /// The checks across keys print extreme values in exponent form, not as hundreds of
    /// digits (or as `0.0000`).
    #[test]
    fn checks_across_keys_print_extreme_values_in_exponent_form() {
        type Spoil = fn(&mut SpecimenSpec);
        let cases: [(Spoil, &str); 5] = [
            (|s| s.gradation[0].size = 1e300, "particles of 1e300 m"),
            (|s| s.membrane_thickness = 1e300, "1e300 m leaves no room"),
            (|s| s.height = 1e-300, "height 1e-300 m"),
            (
                |s| s.test.target_strain = 1e-300,
                "test.target_strain = 1e-300",
            ),
            (
                |s| {
                    s.solid_fraction = None;
                    s.particles = Some(1);
                    s.height = 1e200;
                },
                "solid fraction 1.",
            ),
        ];
        for (spoil, fragment) in cases {
            let mut spec = crate::quick_spec();
            spoil(&mut spec);
            let e = spec.validate("code").unwrap_err().to_string();
            assert!(e.contains(fragment), "{fragment}: {e}");
            assert!(!e.contains("0000000000"), "{e}");
        }
    }

    /// Sizes and contact lengths follow h; with exact scaling the parameters follow
    /// Table 1 (only the penalty changes, and only parameters are listed as scaled).
    #[test]
    fn simulated_scales_sizes_lengths_and_with_exact_scaling_the_parameters() {
        let mut spec = crate::quick_spec();
        spec.coarse_graining = 2.0;
        spec.contact.depth_limit = Some(0.003);
        spec.preparation.friction = 0.1;
        for exact in [false, true] {
            spec.exact_scaling = exact;
            let s = spec.simulated().unwrap();
            assert_eq!(s.sizes, [0.075]);
            assert_eq!(s.contact.margin, Some(0.008));
            assert_eq!(s.contact.depth_limit, Some(0.006));
            assert_eq!(s.material, spec.material);
            assert_eq!(s.preparation_friction, 0.1);
            let penalty = if exact { 2.25e10 } else { 4.5e10 };
            assert_eq!(s.contact.normal_penalty, penalty);
            let keys: Vec<&str> = s.scaled.iter().map(|(k, _, _)| k.as_str()).collect();
            let expected: &[&str] = if exact {
                &["contact.normal_penalty"]
            } else {
                &[]
            };
            assert_eq!(keys, expected);
        }
    }
}
