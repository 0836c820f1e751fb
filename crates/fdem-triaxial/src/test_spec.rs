//! The `[membrane]` and `[test]` sections of a specimen definition: the flexible membrane
//! and the loading of the triaxial test (docs/TRIAXIAL.md has the schema and the reasons
//! for every default).

use fdem_core::number::Number;
use fdem_solver::toml_input::{
    at_least_one, check_fraction, fraction, fraction_opt, non_negative, non_negative_opt, poisson,
    positive, positive_opt,
};
use serde::{Deserialize, Deserializer, Serialize, de::Error as _};

/// Largest target axial strain accepted (a logarithmic strain of 0.5 is a height ratio
/// of 0.61: beyond it the membrane mesh and the measurement lose meaning).
pub const MAX_TARGET_STRAIN: f64 = 0.5;
/// Fewest membrane divisions around the circumference chosen by default (about 40 in the
/// one open cylindrical-triaxial code with a membrane, docs/MODEL.md section 6).
pub const MIN_DIVISIONS_AROUND: usize = 40;
/// Default membrane node spacing as a fraction of the smallest simulated particle
/// diameter: three nodes per particle diameter, so a particle touches several membrane
/// faces and no particle vertex fits through a face.
pub const MEMBRANE_SPACING: f64 = 1.0 / 3.0;

/// `[membrane]`: the latex sleeve that replaces the preparation cylinder (its thickness is
/// the top-level `membrane_thickness`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MembraneSection {
    /// Young's modulus (Pa), > 0. Default 40e6: stiffer than latex (about 1 MPa) on
    /// purpose; a 1 MPa sleeve under 0.8 MPa wraps coarse particles and keeps sinking into
    /// the surface voids (docs/TRIAXIAL.md, "Why a 40 MPa membrane by default").
    #[serde(default = "default_membrane_modulus", deserialize_with = "positive")]
    pub youngs_modulus: f64,
    /// Poisson's ratio, in (-1, 0.5). Default 0.45.
    #[serde(default = "default_membrane_poisson", deserialize_with = "poisson")]
    pub poisson_ratio: f64,
    /// Density (kg/m^3), > 0. Default 1100 (latex).
    #[serde(default = "default_membrane_density", deserialize_with = "positive")]
    pub density: f64,
    /// Viscous damping of the membrane's radial motion (Pa s/m), >= 0: a traction
    /// `-c v_r` on every node's area, standing for the cell fluid; it keeps the light
    /// membrane from slamming into the particles when the pressure is applied. Default
    /// 8e4: the terminal speed under 0.8 MPa is 10 m/s, and the traction at the radial
    /// speeds of a quasi-static test (below 0.05 m/s) is below 0.5 % of sigma_0.
    #[serde(
        default = "default_membrane_damping",
        deserialize_with = "non_negative"
    )]
    pub damping: f64,
    /// Horizontal membrane speed (m/s) above which a stiff damping limiter acts (see
    /// docs/TRIAXIAL.md), > 0. Default: the loading velocity, above the radial speeds
    /// of a quasi-static test (the bulge grows at a fraction of the platen speed) and far
    /// below those of a sheet pressed into the surface voids by sigma_0.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub speed_limit: Option<f64>,
    /// Mass of cell fluid moving with the membrane (kg/m^2), >= 0, added to the
    /// membrane's lumped masses. Default: half the water density times the inner radius,
    /// the added mass of a cylinder expanding in a large body of water (1000 r / 2).
    #[serde(
        default,
        deserialize_with = "non_negative_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub added_mass: Option<f64>,
    /// Elements around the circumference, >= 3. Default: the larger of 40 and the count
    /// giving a spacing of a third of the smallest simulated particle diameter.
    #[serde(
        default,
        deserialize_with = "divisions_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub divisions_around: Option<usize>,
    /// Element rows along the height, >= 1. Default: square cells (the height over the
    /// circumferential spacing, rounded up).
    #[serde(
        default,
        deserialize_with = "divisions_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub divisions_along: Option<usize>,
}

impl Default for MembraneSection {
    fn default() -> Self {
        MembraneSection {
            youngs_modulus: default_membrane_modulus(),
            poisson_ratio: default_membrane_poisson(),
            density: default_membrane_density(),
            damping: default_membrane_damping(),
            speed_limit: None,
            added_mass: None,
            divisions_around: None,
            divisions_along: None,
        }
    }
}

impl MembraneSection {
    /// Divisions `(around, along)` of a membrane of `radius` and `height` around
    /// particles whose smallest simulated diameter is `d_min`.
    pub fn divisions(&self, radius: f64, height: f64, d_min: f64) -> (usize, usize) {
        let circumference = std::f64::consts::TAU * radius;
        let around = self.divisions_around.unwrap_or_else(|| {
            let by_size = (circumference / (MEMBRANE_SPACING * d_min)).ceil();
            // Saturating float-to-int conversion: absurd ratios give usize::MAX, which the
            // membrane's own check then refuses with a message.
            (by_size as usize).max(MIN_DIVISIONS_AROUND)
        });
        let along = self.divisions_along.unwrap_or_else(|| {
            let spacing = circumference / around.max(1) as f64;
            ((height / spacing).ceil() as usize).max(1)
        });
        (around, along)
    }
}

/// `[test]`: consolidation, shear and outputs of the triaxial test.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TestSection {
    /// Axial (logarithmic) strain at which shearing stops, in (0, 0.5]. Default 0.15.
    #[serde(default = "default_target_strain", deserialize_with = "target_strain")]
    pub target_strain: f64,
    /// Inertial number `I = eps_rate d sqrt(rho / sigma_0)` of the default loading
    /// velocity, with `d` the series' largest simulated size; in (0, 1]. Default 1e-3.
    #[serde(default = "default_inertial_number", deserialize_with = "fraction")]
    pub inertial_number: f64,
    /// Largest simulated particle diameter (m) of the coarse-graining series the specimen
    /// belongs to: the default loading velocity keeps the inertial number of that, the
    /// coarsest, member at `inertial_number`, and every member of the series shares the
    /// velocity. Default: this specimen's largest simulated diameter (the paper's presets
    /// set 0.060 m, the coarsest size of both series).
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub series_size: Option<f64>,
    /// Axial strain between two rows of curve.csv during shear, > 0. Default 0.001.
    #[serde(default = "default_output_strain", deserialize_with = "positive")]
    pub output_strain: f64,
    /// Consolidation ends when the axial stress is within this fraction of sigma_0,
    /// in (0, 1]. Default 0.01.
    #[serde(default = "default_stress_tolerance", deserialize_with = "fraction")]
    pub stress_tolerance: f64,
    /// ... and the unbalanced-force ratio is at most this, in (0, 1]. Default 0.02.
    #[serde(default = "default_unbalanced", deserialize_with = "fraction")]
    pub unbalanced_force: f64,
    /// ... and the kinetic energy is at most this fraction of the stored (strain, contact
    /// and membrane) energy, in (0, 1]. Default 0.05: the particles' elastic vibrations
    /// have no material damping and keep a few percent of the stored energy.
    #[serde(default = "default_kinetic_ratio", deserialize_with = "fraction")]
    pub kinetic_ratio: f64,
    /// ... and the volume changes at most this fraction of the shear's axial strain rate
    /// (v / H) between two checks, > 0: the membrane has stopped sinking into the surface
    /// voids. Default 0.1.
    #[serde(default = "default_volume_rate", deserialize_with = "positive")]
    pub volume_rate: f64,
    /// Longest consolidation (s), > 0. Default: the time the platen takes to move 10 % of
    /// the height at the loading velocity.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub consolidation_time: Option<f64>,
    /// Time (s) over which the membrane pressure and the servo's target rise from the
    /// lateral stress the preparation left to sigma_0, > 0. Default: the time the platen
    /// takes to move 1 % of the height at the loading velocity.
    #[serde(
        default,
        deserialize_with = "positive_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub ramp_time: Option<f64>,
    /// Steps between two checks of the consolidation criterion, >= 1. Default 500.
    #[serde(default = "default_check_steps", deserialize_with = "at_least_one")]
    pub check_interval: u64,
    /// Fastest platen speed of the consolidation servo, as a multiple of the loading
    /// velocity, > 0. Default 2.
    #[serde(default = "default_servo_speed", deserialize_with = "positive")]
    pub servo_speed: f64,
    /// Relative stress error at which the servo runs at its fastest, in (0, 1]; below it
    /// the speed is proportional to the error. Default 0.25.
    #[serde(default = "default_servo_band", deserialize_with = "fraction")]
    pub servo_band: f64,
    /// Axial strain over whose end the residual stress ratio is averaged, > 0. Default
    /// 0.02.
    #[serde(default = "default_residual_window", deserialize_with = "positive")]
    pub residual_window: f64,
    /// Fraction of the assembled test's stable bound (the smallest of the elements'
    /// eigenvalue bounds, the contact springs and the membrane elements) used as the time
    /// step, in (0, 1]. Default [`TEST_DT_SAFETY`] for both models (docs/TRIAXIAL.md,
    /// "Time step"; [`TestSection::dt_safety`]).
    #[serde(
        default,
        deserialize_with = "fraction_opt",
        skip_serializing_if = "Option::is_none"
    )]
    pub dt_safety: Option<f64>,
}

impl Default for TestSection {
    fn default() -> Self {
        TestSection {
            target_strain: default_target_strain(),
            inertial_number: default_inertial_number(),
            series_size: None,
            output_strain: default_output_strain(),
            stress_tolerance: default_stress_tolerance(),
            unbalanced_force: default_unbalanced(),
            kinetic_ratio: default_kinetic_ratio(),
            volume_rate: default_volume_rate(),
            consolidation_time: None,
            ramp_time: None,
            check_interval: default_check_steps(),
            servo_speed: default_servo_speed(),
            servo_band: default_servo_band(),
            residual_window: default_residual_window(),
            dt_safety: None,
        }
    }
}

impl TestSection {
    /// The test's `dt_safety`: the given one, else [`TEST_DT_SAFETY`].
    pub fn dt_safety(&self) -> f64 {
        self.dt_safety.unwrap_or(TEST_DT_SAFETY)
    }

    /// Cross-field checks that deserialization cannot make alone (for definitions built
    /// in code): the same rules, as `(key, message)`.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        check_target_strain(self.target_strain).map_err(|m| ("test.target_strain", m))?;
        check_fraction(self.inertial_number).map_err(|m| ("test.inertial_number", m))?;
        if let Some(f) = self.dt_safety {
            check_fraction(f).map_err(|m| ("test.dt_safety", m))?;
        }
        if self.output_strain >= self.target_strain {
            return Err((
                "test.output_strain",
                format!(
                    "{} is not below test.target_strain = {}; give a smaller output interval",
                    Number(self.output_strain),
                    Number(self.target_strain)
                ),
            ));
        }
        Ok(())
    }
}

fn default_membrane_modulus() -> f64 {
    40.0e6
}
fn default_membrane_poisson() -> f64 {
    0.45
}
fn default_membrane_density() -> f64 {
    1100.0
}
fn default_membrane_damping() -> f64 {
    8.0e4
}
fn default_target_strain() -> f64 {
    0.15
}
/// Default `test.dt_safety`, for deformable and rigid particles alike: the bound combines
/// every stiffness on a node (elements or membrane with the contact springs), and the
/// deformable particles' assembled bound lies above their elements' (docs/TRIAXIAL.md,
/// "Time step").
pub const TEST_DT_SAFETY: f64 = 0.8;
fn default_inertial_number() -> f64 {
    1e-3
}
fn default_output_strain() -> f64 {
    0.001
}
fn default_stress_tolerance() -> f64 {
    0.01
}
fn default_unbalanced() -> f64 {
    0.02
}
fn default_kinetic_ratio() -> f64 {
    0.05
}
fn default_volume_rate() -> f64 {
    0.1
}
fn default_check_steps() -> u64 {
    500
}
fn default_servo_speed() -> f64 {
    2.0
}
fn default_servo_band() -> f64 {
    0.25
}
fn default_residual_window() -> f64 {
    0.02
}

fn check_target_strain(v: f64) -> Result<f64, String> {
    if v > 0.0 && v <= MAX_TARGET_STRAIN {
        Ok(v)
    } else {
        Err(format!(
            "must lie in (0, {MAX_TARGET_STRAIN}] (a logarithmic axial strain), got {}",
            Number(v)
        ))
    }
}

fn target_strain<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    check_target_strain(f64::deserialize(d)?).map_err(D::Error::custom)
}

fn divisions_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<usize>, D::Error> {
    let v = u64::deserialize(d)?;
    if (1..=100_000).contains(&v) {
        Ok(Some(v as usize))
    } else {
        Err(D::Error::custom(format!(
            "must be a whole number in [1, 100000], got {v}"
        )))
    }
}

impl crate::SpecimenSpec {
    /// Steps of the shear with time step `dt`: the platen moves at the loading velocity
    /// until the logarithmic axial strain reaches `test.target_strain`, a travel of
    /// `H (1 - exp(-eps))` (eq 12).
    pub fn shear_steps(&self, dt: f64) -> u64 {
        let travel = self.height * (1.0 - (-self.test.target_strain).exp());
        (travel / (self.loading_velocity() * dt)).ceil() as u64
    }

    /// The definition with the settings that only the test uses (`[test]`, `[membrane]`,
    /// `loading_velocity`) reset to their defaults, and the defaults that depend on the
    /// model made explicit (`preparation.max_overlap`): two definitions with equal keys are
    /// prepared identically, so a prepared specimen can be reused for either.
    pub fn preparation_key(&self) -> crate::SpecimenSpec {
        crate::SpecimenSpec {
            test: TestSection::default(),
            membrane: MembraneSection::default(),
            loading_velocity: None,
            preparation: crate::PreparationSection {
                max_overlap: Some(self.max_overlap()),
                ..self.preparation.clone()
            },
            ..self.clone()
        }
    }
}

/// The quick test (`--quick`): a small, coarse specimen that runs end to end in a short
/// time on 2 threads, for tests and for trying things out. Not a paper test: phi 150 x
/// 225 mm, 37.5 mm level-1 linear particles (D/d = 4, 84 particles, nominal solid
/// fraction 0.62, jammed at the target height), softer grains (E = 10 GPa) with the
/// paper's E1 penalty, a contact margin of 4 mm (twice the default, for the membrane
/// draped over the coarse particles) and an inertial number of 5e-3; prepared at half
/// the stable bound with a 3 % overlap limit. docs/TRIAXIAL.md gives the reasons ("The
/// quick specimen") and the measured cost ("Measured runs").
pub fn quick_spec() -> crate::SpecimenSpec {
    let text = r#"
name = "quick"
diameter = 0.150
height = 0.225
solid_fraction = 0.62
gradation = [{ size = 0.0375, mass_fraction = 1.0 }]

[material]
density = 2650.0
youngs_modulus = 10.0e9
poisson_ratio = 0.2

[contact]
normal_penalty = 4.5e10
margin = 0.004

[mesh]
level = 1
order = "linear"

[preparation]
loose_solid_fraction = 0.40
dt_safety = 0.5
max_overlap = 0.03

[test]
inertial_number = 5e-3
output_strain = 0.0025
"#;
    // The text is fixed and checked by a test; a failure here is a programming error.
    crate::SpecimenSpec::from_toml_str(text, "quick test").expect("the quick specimen is valid")
}
