//! Preparation by the dynamic method on small specimens, specimen files, and the restore
//! of the friction history.
//!
//! The specimens are a few dozen level-0 linear particles of a soft material (E = 100 MPa,
//! so that the stable step is long) in a phi 104 x 60 mm cylinder, so that a preparation
//! takes few steps (docs/SPECIMENS.md, "Verification", has its step count and time).

use fdem_contact::Counterpart;
use fdem_mesh::{SphereSpec, sphere_mesh};
use fdem_triaxial::{
    Observer, Phase, PreparedSpecimen, Silent, SpecimenSpec, Status, TriaxialError, WALL_BOTTOM,
    WALL_CYLINDER, WALL_TOP, prepare, sphere_volume, unbalanced_force_ratio,
};
use std::sync::OnceLock;

const SMALL: &str = r#"
name = "small"
diameter = 0.104
height = 0.06
solid_fraction = 0.5
gradation = [{ size = 0.02, mass_fraction = 1.0 }]

[material]
density = 2650.0
youngs_modulus = 1.0e8
poisson_ratio = 0.2

[contact]
normal_penalty = 1.0e9

[mesh]
level = 0
order = "linear"

# A loose start (the old random sequential placement's): over 1000 compaction steps.
[preparation]
loose_solid_fraction = 0.25
"#;

/// The same specimen under gravity (50 m/s^2, to settle quickly) with friction during
/// preparation: it ends as a pile on the bottom platen with sticking contacts, so the
/// friction history is not trivial.
fn gravity_text() -> String {
    format!("{SMALL}friction = 0.3\ngravity = [0.0, 0.0, -50.0]\nsettle_time = 0.3\n")
}

fn small() -> &'static PreparedSpecimen {
    static CELL: OnceLock<PreparedSpecimen> = OnceLock::new();
    CELL.get_or_init(|| {
        let spec = SpecimenSpec::from_toml_str(SMALL, "small").unwrap();
        prepare(&spec, &mut Silent).unwrap()
    })
}

/// The mesh of one particle of the small specimen (level 0, linear, 20 mm inscribed).
fn small_particle_mesh() -> fdem_mesh::TetMesh {
    sphere_mesh(&SphereSpec {
        level: 0,
        order: fdem_mesh::ElementOrder::Linear,
        diameter: 0.02,
        sizing: fdem_mesh::Sizing::Inscribed,
    })
    .unwrap()
}

/// The small specimen with rigid particles.
fn small_rigid() -> &'static PreparedSpecimen {
    static CELL: OnceLock<PreparedSpecimen> = OnceLock::new();
    CELL.get_or_init(|| {
        let text = format!("model = \"rigid\"\n{SMALL}");
        let spec = SpecimenSpec::from_toml_str(&text, "small rigid").unwrap();
        prepare(&spec, &mut Silent).unwrap()
    })
}

/// The small specimen with two size classes and `model = "auto"`, its threshold between
/// the two classes' estimated ratios: the small particles rigid, the large deformable.
fn small_mixed() -> &'static PreparedSpecimen {
    static CELL: OnceLock<PreparedSpecimen> = OnceLock::new();
    CELL.get_or_init(|| {
        let text = format!("model = \"auto\"\n{SMALL}").replace(
            "gradation = [{ size = 0.02, mass_fraction = 1.0 }]",
            "gradation = [{ size = 0.02, mass_fraction = 0.5 }, { size = 0.03, mass_fraction = 0.5 }]",
        );
        let mut spec = SpecimenSpec::from_toml_str(&text, "small mixed").unwrap();
        let ratios: Vec<f64> = spec
            .counts()
            .unwrap()
            .classes
            .iter()
            .map(|c| c.auto.unwrap().ratio)
            .collect();
        spec.auto_threshold = Some((ratios[0] * ratios[1]).sqrt());
        prepare(&spec, &mut Silent).unwrap()
    })
}

fn pile() -> &'static PreparedSpecimen {
    static CELL: OnceLock<PreparedSpecimen> = OnceLock::new();
    CELL.get_or_init(|| {
        let spec = SpecimenSpec::from_toml_str(&gravity_text(), "pile").unwrap();
        prepare(&spec, &mut Silent).unwrap()
    })
}

#[test]
fn compaction_reaches_the_target_height_with_the_solid_fraction_it_implies() {
    let s = small();
    let r = &s.report;
    let spec = &s.spec;
    assert!(r.checks.passed(), "{:?}", r.checks);
    assert_eq!(r.particles, 56);
    // The platens closed by exactly the loose height minus the target.
    let travel = r.platen_speed * r.dt * r.compact_steps as f64;
    assert!((travel - (r.loose_height - spec.height)).abs() < 1e-12 * r.loose_height);
    // The placement reached the requested loose fraction (the column did not grow): the
    // loose height is the one it implies, rounded up to a whole number of steps.
    let solids = r.particles as f64 * sphere_volume(0.02);
    let requested = solids / (spec.preparation.loose_solid_fraction * spec.inner_area());
    let step = r.platen_speed * r.dt;
    assert!(
        r.loose_height >= requested * (1.0 - 1e-12) && r.loose_height < requested + step,
        "loose column {} m, requested {requested} m",
        r.loose_height
    );
    // The walls of the prepared configuration: cylinder, platens at z = 0 and z = H.
    let scene = s.scene().unwrap();
    assert_eq!(scene.walls[WALL_CYLINDER].radius, Some(spec.inner_radius()));
    assert_eq!(scene.walls[WALL_BOTTOM].point, Some([0.0, 0.0, 0.0]));
    assert_eq!(scene.walls[WALL_TOP].point, Some([0.0, 0.0, spec.height]));
    // Every node inside, within the stated overlap.
    let tol = r.checks.overlap_limit;
    let radius = spec.inner_radius();
    for x in &s.state.positions {
        assert!((x[0] * x[0] + x[1] * x[1]).sqrt() <= radius + tol);
        assert!(x[2] >= -tol && x[2] <= spec.height + tol);
    }
    // Solid fraction: nominal from the count rule; real = nominal x (mesh volume / sphere
    // volume) of the inscribed level-0 mesh, up to the particles' elastic deformation.
    let nominal = 56.0 * sphere_volume(0.02) / spec.inner_volume();
    assert!((r.solid_fraction_nominal - nominal).abs() < 1e-14);
    let mesh = small_particle_mesh();
    let ratio = mesh.volume() / sphere_volume(0.02);
    assert!((ratio - 0.6055).abs() < 1e-4);
    let expected = nominal * ratio;
    assert!(
        (r.solid_fraction_real - expected).abs() < 1e-4 * expected,
        "{} vs {expected}",
        r.solid_fraction_real
    );
    // At rest.
    assert!(s.state.velocities.iter().all(|v| *v == [0.0; 3]));
    assert!(r.settled);
    assert!(r.wall_seconds > 0.0 && r.compact_steps > 1000);
}

#[test]
fn a_pile_under_gravity_keeps_a_friction_history() {
    let s = pile();
    assert!(s.report.checks.passed(), "{:?}", s.report.checks);
    assert!(
        s.report.coordination_number > 2.0,
        "{}",
        s.report.coordination_number
    );
    let sticking = s
        .state
        .history
        .iter()
        .filter(|h| h.2 != [0.0; 3] && matches!(h.1, Counterpart::Body(_)))
        .count();
    assert!(
        sticking > 20,
        "{sticking} particle contacts with a tangential displacement"
    );
    assert!(
        s.state
            .history
            .iter()
            .any(|h| h.1 == Counterpart::Wall(WALL_BOTTOM as u32))
    );
}

#[test]
fn a_restored_specimen_reproduces_the_checked_state_exactly() {
    for s in [small(), pile()] {
        let sim = s.simulation().unwrap();
        assert_eq!(sim.state().positions, s.state.positions);
        assert_eq!(sim.state().velocities, s.state.velocities);
        assert_eq!(sim.time(), s.state.time);
        assert_eq!(sim.step(), s.state.step);
        assert_eq!(sim.dt(), s.dt);
        // The checks were made on the state after the final restore in `prepare`; a
        // fresh restore gives the same forces to the last bit.
        let d = s.spec.simulated().unwrap().sizes[0];
        let f_ref = s.spec.confining_pressure * d * d;
        assert_eq!(
            unbalanced_force_ratio(&sim, f_ref).to_bits(),
            s.report.checks.unbalanced_force.to_bits()
        );
    }
}

#[test]
fn a_rigid_specimen_is_prepared_with_its_poses_and_no_elements() {
    let s = small_rigid();
    let r = &s.report;
    assert!(r.checks.passed(), "{:?}", r.checks);
    assert_eq!((r.particles, r.elements), (56, 0));
    assert_eq!(s.state.rigid.len(), 56);
    // Every rigid particle rests: the final stop zeroed its momenta.
    for state in &s.state.rigid {
        assert_eq!(state.velocity, [0.0; 3]);
        assert_eq!(state.body_momentum, [0.0; 3]);
    }
    // The nodes are where the poses put them once restored.
    let sim = s.simulation().unwrap();
    assert_eq!(bits(&sim.state().positions), bits(&s.state.positions));
    // The solid fraction counts the rigid volumes: exactly the meshes' volume, the
    // inscribed icosahedron's 0.6055 of the sphere's (rigid particles do not deform).
    let mesh = small_particle_mesh();
    let expected = r.solid_fraction_nominal * mesh.volume() / sphere_volume(0.02);
    assert!(
        (r.solid_fraction_real - expected).abs() < 1e-12 * expected,
        "{} vs {expected}",
        r.solid_fraction_real
    );
    // Refused: a deformable state into the rigid model.
    let mut other = small().state.clone();
    other.rigid = vec![];
    assert!(
        other
            .restore_into(&mut s.simulation().unwrap(), true)
            .is_err()
    );
}

/// `model = "auto"` resolves per size class: with a threshold between the two classes'
/// estimated ratios (the ratio grows with the diameter at a fixed penalty), the small
/// class is rigid and the large one deformable, in the counts, the prepared model and
/// the saved state.
#[test]
fn an_auto_specimen_mixes_rigid_and_deformable_classes() {
    let s = small_mixed();
    let counts = s.spec.counts().unwrap();
    let models: Vec<_> = counts.classes.iter().map(|c| c.model).collect();
    assert_eq!(
        models,
        [
            fdem_solver::ParticleModel::Rigid,
            fdem_solver::ParticleModel::Deformable
        ]
    );
    let (small, large) = (counts.classes[0].particles, counts.classes[1].particles);
    assert_eq!(counts.rigid_particles, small);
    assert!(s.report.checks.passed(), "{:?}", s.report.checks);
    assert_eq!(s.state.rigid.len() as u64, small);
    assert_eq!(
        s.report.elements,
        large * counts.classes[1].elements_per_particle
    );
    let sim = s.simulation().unwrap();
    for (p, (_, body)) in s.particles.iter().zip(sim.particles()) {
        let rigid = body.kind == fdem_solver::BodyKind::Rigid;
        assert_eq!(rigid, p.class == 0, "class {} is {:?}", p.class, body.kind);
    }
}

/// A prepared packing changes model in place: deformable to rigid puts every rigid
/// particle's centre on the deformed particle's mass centroid (1e-12 of a diameter) and
/// its surface nodes on the deformable surface nodes within their deformation (below
/// 0.1 % of a diameter in this loose packing); back to deformable the meshes sit
/// undeformed at those poses, and to rigid again the poses come back (1e-12). The
/// converted specimens build, restore and step.
#[test]
fn a_packing_changes_model_in_place() {
    use fdem_solver::ParticleModel::{Deformable, Rigid};
    let s = small();
    let rigid = s.in_model(Rigid).unwrap();
    assert_eq!(rigid.spec.model, Rigid);
    assert_eq!(rigid.state.rigid.len(), s.particles.len());
    assert!(rigid.state.history.is_empty());
    let (from, to) = (s.simulation().unwrap(), rigid.simulation().unwrap());
    let d = 0.02;
    let mut worst = 0.0f64;
    for (((id, a), (_, b)), state) in from.particles().zip(to.particles()).zip(&rigid.state.rigid) {
        let c = from.body_motion(id).centroid;
        let e = (0..3)
            .map(|k| (c[k] - state.position[k]).abs())
            .fold(0.0, f64::max);
        assert!(e < 1e-12 * d, "centre off by {e}");
        // Rigid node k is deformable surface node k (the sphere's surface nodes first).
        for (k, n) in b.nodes.clone().enumerate() {
            let (x, y) = (
                from.state().positions[a.nodes.start + k],
                to.state().positions[n],
            );
            worst = worst.max((0..3).map(|j| (x[j] - y[j]).abs()).fold(0.0, f64::max));
        }
    }
    eprintln!("surface nodes of the two models differ by at most {worst:.3e} m");
    assert!(worst < 1e-3 * d, "{worst}");
    let back = rigid.in_model(Deformable).unwrap();
    assert!(back.state.rigid.is_empty());
    let again = back.in_model(Rigid).unwrap();
    for (p, q) in again.state.rigid.iter().zip(&rigid.state.rigid) {
        for k in 0..3 {
            assert!((p.position[k] - q.position[k]).abs() < 1e-12 * d);
        }
        let dot: f64 = (0..4).map(|k| p.orientation[k] * q.orientation[k]).sum();
        assert!(1.0 - dot.abs() < 1e-12, "{dot}");
    }
    for specimen in [&rigid, &back] {
        let mut sim = specimen.simulation().unwrap();
        for _ in 0..20 {
            sim.advance().unwrap();
        }
    }
}

fn bits(v: &[[f64; 3]]) -> Vec<[u64; 3]> {
    v.iter().map(|x| x.map(f64::to_bits)).collect()
}

#[test]
fn a_saved_specimen_reloads_bit_for_bit_and_steps_identically() {
    let dir = tempfile::tempdir().unwrap();
    for (s, name) in [
        (small(), "small.fdemspec"),
        (pile(), "pile.fdemspec"),
        (small_rigid(), "rigid.fdemspec"),
        (small_mixed(), "mixed.fdemspec"),
    ] {
        let path = dir.path().join(name);
        s.save(&path).unwrap();
        assert!(!dir.path().join(format!("{name}.part")).exists());
        let loaded = PreparedSpecimen::load(&path).unwrap();
        // Every field, floats compared exactly (PartialEq on f64 is bitwise here: no NaN).
        assert_eq!(&loaded, s);
        assert_eq!(bits(&loaded.state.positions), bits(&s.state.positions));
        // The un-saved specimen and the reloaded one step to the same bits.
        let mut a = s.simulation().unwrap();
        let mut b = loaded.simulation().unwrap();
        for _ in 0..50 {
            a.advance().unwrap();
            b.advance().unwrap();
        }
        assert_eq!(bits(&a.state().positions), bits(&b.state().positions));
        assert_eq!(bits(&a.state().velocities), bits(&b.state().velocities));
        let (ha, hb) = (
            a.contact().unwrap().model().export_history(),
            b.contact().unwrap().model().export_history(),
        );
        assert_eq!(ha, hb);
        assert_eq!(
            a.energy().balance_error.to_bits(),
            b.energy().balance_error.to_bits()
        );
    }
}

fn refusal(bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.fdemspec");
    std::fs::write(&path, bytes).unwrap();
    match PreparedSpecimen::load(&path) {
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "one line: {m}");
            m
        }
        Ok(_) => panic!("a damaged file was accepted"),
    }
}

/// FNV-1a 64, the specimen file's checksum, to write a whole file of another version.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[test]
fn damaged_or_foreign_files_are_refused_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("good.fdemspec");
    small().save(&path).unwrap();
    let good = std::fs::read(&path).unwrap();

    let m = refusal(&good[..good.len() - 100]);
    assert!(m.contains("truncated"), "{m}");
    let m = refusal(&good[..good.len() / 2]);
    assert!(m.contains("truncated"), "{m}");
    let m = refusal(&good[..10]);
    assert!(m.contains("truncated"), "{m}");

    let mut flipped = good.clone();
    let middle = good.len() - 5000;
    flipped[middle] ^= 0x10;
    assert!(refusal(&flipped).contains("checksum"));

    // A changed digit in the TOML header.
    let mut header = good.clone();
    let at = good.windows(6).position(|w| w == b"height").unwrap() + 9;
    header[at] = if header[at] == b'1' { b'2' } else { b'1' };
    assert!(refusal(&header).contains("checksum"));

    // A whole file (its checksum holds) of a later format version.
    let mut version = good.clone();
    version[8..12].copy_from_slice(&3u32.to_le_bytes());
    let end = version.len() - 8;
    let sum = fnv(&version[..end]);
    version[end..].copy_from_slice(&sum.to_le_bytes());
    let m = refusal(&version);
    assert!(
        m.contains("format version 3") && m.contains("versions 1 to 2"),
        "{m}"
    );

    let mut longer = good.clone();
    longer.extend_from_slice(b"tail");
    assert!(refusal(&longer).contains("4 more"));

    assert!(refusal(b"diameter = 0.3\n").contains("not an fdem specimen file"));
}

/// Every cut of a specimen file is called truncated, and every changed byte (one bit,
/// at every offset of the preamble, the header and the counts, and at a stride through
/// the rest) corrupted, never truncated: a changed count does not pass for a cut.
#[test]
fn cuts_are_truncations_and_changed_bytes_corruptions() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("good.fdemspec");
    small_rigid().save(&path).unwrap();
    let good = std::fs::read(&path).unwrap();
    let header_len = u64::from_le_bytes(good[12..20].try_into().unwrap()) as usize;
    let counts_end = 20 + header_len + 4 * 8;

    let cuts = (0..counts_end + 64)
        .chain((counts_end..good.len()).step_by(97))
        .chain(good.len() - 16..good.len());
    let mut n_cuts = 0;
    for cut in cuts {
        let m = refusal(&good[..cut]);
        assert!(m.contains("truncated"), "cut at {cut}: {m}");
        n_cuts += 1;
    }

    let offsets = (0..counts_end)
        .chain((counts_end..good.len()).step_by(89))
        .chain(good.len() - 8..good.len());
    let mut n_flips = 0;
    for at in offsets {
        let mut bad = good.clone();
        bad[at] ^= 1 << (at % 8);
        let m = refusal(&bad);
        let expected = if at < 8 {
            "not an fdem specimen file"
        } else {
            "corrupted"
        };
        assert!(
            m.contains(expected) && !m.contains("truncated"),
            "bit {} of byte {at} changed: {m}",
            at % 8
        );
        n_flips += 1;
    }
    eprintln!("{n_cuts} cuts and {n_flips} changed bytes refused");
}

#[test]
fn history_export_and_import_round_trip_and_refuse_foreign_entries() {
    let s = pile();
    let mut sim = s.simulation().unwrap();
    let model = sim.contact_mut().unwrap().model_mut();
    let exported = model.export_history();
    assert!(!exported.is_empty());
    model.import_history(&exported).unwrap();
    assert_eq!(model.export_history(), exported);
    let first = exported[0];
    let n_nodes = s.state.positions.len();
    let cases = [
        vec![(n_nodes + 5, first.1, first.2)],
        vec![(first.0, Counterpart::Wall(3), first.2)],
        vec![(first.0, Counterpart::Body(999), first.2)],
        vec![(first.0, first.1, [f64::NAN, 0.0, 0.0])],
        vec![first, first],
    ];
    for bad in cases {
        assert!(model.import_history(&bad).is_err(), "{bad:?}");
        // Nothing changed.
        assert_eq!(model.export_history(), exported);
    }
}

#[test]
fn an_observer_can_interrupt_and_sees_every_phase() {
    struct Stop(Vec<Phase>);
    impl Observer for Stop {
        fn phase(&mut self, phase: Phase, _: u64) {
            self.0.push(phase);
        }
        fn progress(&mut self, phase: Phase, status: &Status) -> bool {
            !(phase == Phase::Compact && status.step >= 1000)
        }
    }
    let spec = SpecimenSpec::from_toml_str(SMALL, "small").unwrap();
    let mut stop = Stop(Vec::new());
    let err = prepare(&spec, &mut stop).unwrap_err();
    assert!(
        matches!(
            err,
            TriaxialError::Interrupted {
                phase: "compact",
                ..
            }
        ),
        "{err}"
    );
    assert_eq!(stop.0, [Phase::Place, Phase::Compact]);
}

fn example(name: &str) -> SpecimenSpec {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/specimens")
        .join(name);
    SpecimenSpec::load(&path).unwrap()
}

#[test]
fn the_example_specimens_parse_and_small_is_the_test_specimen() {
    assert_eq!(
        example("small.toml"),
        SpecimenSpec::from_toml_str(SMALL, "small").unwrap()
    );
    for name in ["dense.toml", "three-sizes.toml", "coarse.toml"] {
        example(name).counts().unwrap();
    }
}

/// The heavier check of docs/SPECIMENS.md: a jammed specimen of level-1 particles.
#[test]
#[ignore = "about 40 s with --release: cargo test --release -p fdem-triaxial -- --ignored"]
fn a_dense_level_1_specimen_jams_settles_and_passes_its_checks() {
    let spec = example("dense.toml");
    let s = prepare(&spec, &mut Silent).unwrap();
    let r = &s.report;
    assert!(r.checks.passed(), "{:?}", r.checks);
    assert!(r.settled);
    // Jammed: a contact network spans the specimen (isostatic frictionless packings have
    // about 6 contacts per particle away from walls; rattlers and walls lower the mean).
    assert!(r.coordination_number > 2.5, "{}", r.coordination_number);
    let mesh = sphere_mesh(&SphereSpec {
        level: 1,
        order: fdem_mesh::ElementOrder::Linear,
        diameter: 0.02,
        sizing: fdem_mesh::Sizing::Inscribed,
    })
    .unwrap();
    let expected = r.solid_fraction_nominal * mesh.volume() / sphere_volume(0.02);
    assert!((r.solid_fraction_real - expected).abs() < 1e-3 * expected);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dense.fdemspec");
    s.save(&path).unwrap();
    assert_eq!(PreparedSpecimen::load(&path).unwrap(), s);
}

#[test]
fn a_compaction_the_contact_law_refuses_stops_with_the_platen_gap() {
    // A contact margin of 1 um: the first impacts move nodes farther than the tunnelling
    // guard allows, as a jammed assembly pushes overlaps past the depth limit.
    let text = SMALL.replace(
        "normal_penalty = 1.0e9",
        "normal_penalty = 1.0e9\nmargin = 1.0e-6",
    );
    let spec = SpecimenSpec::from_toml_str(&text, "tight").unwrap();
    let err = prepare(&spec, &mut Silent).unwrap_err();
    let message = err.to_string();
    assert!(!message.contains('\n'), "{message}");
    match err {
        TriaxialError::Compaction { gap, target, .. } => {
            assert_eq!(target, 0.06);
            assert!(gap > target && gap < 0.14, "{gap}");
        }
        other => panic!("expected a compaction error, got {other}"),
    }
    assert!(
        message.starts_with("compaction stopped at a platen gap of"),
        "{message}"
    );
}
