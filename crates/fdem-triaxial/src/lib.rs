//! # fdem-triaxial: the numerical triaxial test
//!
//! This crate owns the source paper's triaxial test (docs/MODEL.md sections 5-8): what a
//! specimen is, how many particles it holds, how it is prepared, saved and reused, and the
//! test itself: membrane, platens, consolidation, shear, the measurements of eqs 12-15 and
//! the outputs (docs/SPECIMENS.md, docs/TRIAXIAL.md).
//!
//! # What it owns
//! - **Definitions** ([`SpecimenSpec`]): geometry, membrane, gradation (sizes with mass
//!   fractions), nominal solid fraction or particle count, material and contact
//!   parameters, mesh, confining pressure, loading velocity, coarse-graining factor `h`
//!   and exact scaling, and the preparation settings; read from TOML (schema in
//!   docs/SPECIMENS.md) and validated before any work, with one line naming the key.
//!   The twelve tests of the paper's Table 4 are [`PRESETS`].
//! - **Exact scaling of a specimen** ([`SpecimenSpec::simulated`]): particle sizes x h,
//!   and with exact scaling every material and contact parameter times its factor from
//!   `fdem_scaling::ScaleLaw::exact(h)`; no scale factor is typed here.
//! - **The count rule** ([`SpecimenSpec::counts`]): `n_i = floor(V_s f_i / (pi d_i^3 / 6))`
//!   with `V_s = phi pi r^2 H` inside the membrane; elements and nodes from the mesh.
//! - **Placement** ([`place_spheres`]): random non-overlapping spheres in a cylinder,
//!   largest first, through a uniform grid, with random orientations; seeded.
//! - **Preparation by the dynamic method** ([`prepare`]): compaction by two rigid
//!   platens inside a rigid cylinder to the target height, settling, and the checks of the
//!   result ([`Checks`]); progress through an [`Observer`].
//! - **Specimen files** ([`PreparedSpecimen::save`], [`PreparedSpecimen::load`]): a
//!   versioned, checksummed binary format with a TOML header; a reload is bit-for-bit.
//!
//! - **The membrane** ([`MembraneForces`], [`membrane_mesh`]): constant-strain St
//!   Venant-Kirchhoff triangles with a follower pressure, the enclosed volume and
//!   containment of the closed surface with the platens.
//! - **Stability probes** ([`probe`]): the test model run for a few thousand steps at a
//!   multiple of its stable step, classified by what stopped it (docs/STABILITY.md).
//! - **The test** ([`run_test`], [`TestModel`]): servo-controlled consolidation under the
//!   confining pressure, shear at constant platen velocity, `curve.csv`, `summary.json`,
//!   peak contact snapshots, `eta.svg` and `eps_v.svg` ([`CurvePoint`], [`summarize`],
//!   [`plot_curves`]); the quick specimen [`quick_spec`].
//!
//! # What it does not own
//! Time integration, forces and scenes (`fdem-solver`), contact (`fdem-contact`), meshes
//! (`fdem-mesh`), dimensions and scale laws (`fdem-scaling`), progress bars and printing
//! (`fdem-cli`).
//!
//! # Example: the counts of test E1 (paper Table 2)
//! ```
//! use fdem_triaxial::Preset;
//!
//! let counts = Preset::find("E1")?.spec().counts()?;
//! assert_eq!((counts.particles, counts.elements, counts.nodes), (15186, 1214880, 3113130));
//! # Ok::<(), fdem_triaxial::TriaxialError>(())
//! ```
#![warn(missing_docs)]

mod checkpoint;
mod compare;
mod counts;
mod error;
mod file;
mod jumps;
mod loading;
mod measure;
mod membrane;
mod placement;
mod plot;
mod prepare;
mod probe;
mod remodel;
mod spec;
mod test_run;
mod test_spec;

pub use checkpoint::{CHECKPOINT_FILE, CheckpointProgress, checkpoint_progress};
pub use compare::{COMPARISON_HEADER, FinishedRun, RunCost, comparison_row, write_comparison};
pub use counts::{ClassCount, Counts, sphere_volume};
pub use error::TriaxialError;
pub use file::{Cached, FORMAT_VERSION, MAGIC};
pub use jumps::{JUMPS_HEADER, JumpTotal};
pub use loading::{
    TEST_DEPTH_LIMIT_CAP_DIAMETERS, TEST_DEPTH_LIMIT_MARGINS, TEST_FOLD_DEPTH_MARGINS,
    TEST_SKIN_FRACTION, TEST_WALL_BOTTOM, TEST_WALL_MEMBRANE, TEST_WALL_TOP, TestModel,
    membrane_spec,
};
pub use measure::*;
pub use membrane::*;
pub use placement::{Column, MAX_SWEEPS, NoRoom, PlacedParticle, place_spheres, random_rotation};
pub use plot::*;
pub use prepare::{
    COLUMN_GROWTH, COLUMN_TRIES, Checks, FORCE_FLOOR, MAX_NODES, Observer,
    PREPARATION_ENERGY_TOLERANCE, Phase, PreparationReport, PreparedSpecimen, Silent, Snapshot,
    Status, WALL_BOTTOM, WALL_CYLINDER, WALL_TOP, check_memory, particle_sections,
    preparation_walls, prepare, reference_force, specimen_time_step, unbalanced_force_ratio,
};
pub use probe::{ProbeOutcome, STABLE_ENERGY_ERROR, StabilityClass, probe, probe_bound};
pub use spec::{
    DEFAULT_INERTIAL_NUMBER, DEFAULT_SETTLE_DIAMETERS, DEFAULT_SOLID_FRACTION, DENSEST_PACKING,
    FRACTION_SUM_TOLERANCE, MAX_OVERLAP_DEFORMABLE, MAX_OVERLAP_RIGID, ORIGINAL_SIZE, PRESETS,
    PreparationSection, Preset, SERIES_SIZE, Simulated, SizeClass, SpecimenMesh, SpecimenSpec,
    default_material, surface_order,
};
pub use test_run::{
    ConsolidationResult, PhaseCost, SilentTest, TestObserver, TestOptions, TestPhase, TestPlan,
    TestStatus, TestSummary, run_test,
};
pub use test_spec::{
    MAX_TARGET_STRAIN, MEMBRANE_SPACING, MIN_DIVISIONS_AROUND, MembraneSection, TEST_DT_SAFETY,
    TestSection, quick_spec,
};
