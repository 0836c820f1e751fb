//! The catalogue, the count rule, exact scaling of specimens, validation and placement.

use fdem_scaling::ScaleLaw;
use fdem_triaxial::{
    Column, PRESETS, Preset, SpecimenSpec, TriaxialError, place_spheres, random_rotation,
    sphere_volume,
};
use rand::SeedableRng;

/// Table 2 of the paper (docs/MODEL.md section 7): particles, elements, nodes.
const TABLE_2: &[(&str, u64, u64, u64)] = &[
    ("E1", 15186, 1214880, 3113130),
    ("E2", 1898, 151840, 389090),
    ("E3", 562, 44960, 115210),
    ("E4", 237, 18960, 48585),
    ("B1", 8543, 683440, 1751315),
    ("B2", 2532, 202560, 519060),
    ("B3", 1072, 85760, 219760),
];

fn table_2(test: &str) -> (u64, u64, u64) {
    // E2s shares E2's row, and so on.
    let base = test.trim_end_matches('s');
    let row = TABLE_2
        .iter()
        .find(|r| r.0 == base)
        .expect("every preset has a row");
    (row.1, row.2, row.3)
}

#[test]
fn equal_series_counts_are_exactly_table_2() {
    for name in ["E1", "E2", "E3", "E4", "E2s", "E3s", "E4s"] {
        let c = Preset::find(name).unwrap().spec().counts().unwrap();
        assert_eq!((c.particles, c.elements, c.nodes), table_2(name), "{name}");
        let class = &c.classes[0];
        assert_eq!(
            (class.elements_per_particle, class.nodes_per_particle),
            (80, 205)
        );
    }
}

#[test]
fn binary_series_counts_are_within_half_a_percent_of_table_2() {
    for name in ["B1", "B2", "B3", "B2s", "B3s"] {
        let c = Preset::find(name).unwrap().spec().counts().unwrap();
        let (p, e, n) = table_2(name);
        for (got, want, what) in [
            (c.particles, p, "particles"),
            (c.elements, e, "elements"),
            (c.nodes, n, "nodes"),
        ] {
            let rel = (got as f64 - want as f64).abs() / want as f64;
            assert!(
                rel <= 0.005,
                "{name} {what}: {got} vs Table 2 {want} ({rel:.4})"
            );
        }
        // Equal mass: the two classes hold the same solid volume within one coarse particle.
        let v: Vec<f64> = c
            .classes
            .iter()
            .map(|k| k.particles as f64 * sphere_volume(k.diameter))
            .collect();
        assert!(
            (v[0] - v[1]).abs() < sphere_volume(c.classes[1].diameter),
            "{name}"
        );
    }
}

#[test]
fn all_twelve_presets_exist_in_table_4_order() {
    let names: Vec<&str> = PRESETS.iter().map(|p| p.name).collect();
    assert_eq!(
        names,
        [
            "E1", "E2", "E3", "E4", "E2s", "E3s", "E4s", "B1", "B2", "B3", "B2s", "B3s"
        ]
    );
    // Simulated diameters of Table 4.
    let sizes =
        |n: &str| -> Vec<f64> { Preset::find(n).unwrap().spec().simulated().unwrap().sizes };
    assert_eq!(sizes("E3"), [0.045]);
    assert_eq!(sizes("B2s"), [0.0225, 0.045]);
    assert_eq!(sizes("B3"), [0.03, 0.06]);
    assert!(matches!(
        Preset::find("E5"),
        Err(TriaxialError::UnknownTest { .. })
    ));
}

#[test]
fn other_mesh_levels_and_orders_give_their_own_counts() {
    let mut spec = Preset::find("E1").unwrap().spec();
    // MESHES.md: level 0/1/2 tets 20/80/320, linear nodes 13/43/163, quadratic 55/205/805.
    for (level, order, tets, nodes) in [
        (0, fdem_mesh::ElementOrder::Linear, 20, 13),
        (0, fdem_mesh::ElementOrder::Quadratic, 20, 55),
        (1, fdem_mesh::ElementOrder::Linear, 80, 43),
        (2, fdem_mesh::ElementOrder::Quadratic, 320, 805),
    ] {
        spec.mesh.level = level;
        spec.mesh.order = order;
        let c = spec.counts().unwrap();
        assert_eq!(
            (c.particles, c.elements, c.nodes),
            (15186, 15186 * tets, 15186 * nodes)
        );
    }
}

/// The worked example of docs/SPECIMENS.md, "The count rule".
const USER_GRADATION: &str = r#"
name = "three sizes"
diameter = 0.150
height = 0.300
membrane_thickness = 0.001
solid_fraction = 0.60
gradation = [
  { size = 0.010, mass_fraction = 0.2 },
  { size = 0.020, mass_fraction = 0.5 },
  { size = 0.030, mass_fraction = 0.3 },
]
"#;

#[test]
fn count_rule_matches_the_hand_computation_of_the_docs() {
    let spec = SpecimenSpec::from_toml_str(USER_GRADATION, "doc example").unwrap();
    let c = spec.counts().unwrap();
    // n_i = floor(6 phi r^2 H f_i / d_i^3), r = 0.074 m:
    // 6 x 0.60 x 0.074^2 x 0.300 = 5.91408e-3 m^3;
    // x 0.2 / 0.010^3 = 1182.8; x 0.5 / 0.020^3 = 369.6; x 0.3 / 0.030^3 = 65.7.
    let n: Vec<u64> = c.classes.iter().map(|k| k.particles).collect();
    assert_eq!(n, [1182, 369, 65]);
    assert_eq!(
        (c.particles, c.elements, c.nodes),
        (1616, 1616 * 80, 1616 * 205)
    );
    // Every class holds less than one particle below its share of V_s.
    let vs = 0.60 * spec.inner_volume();
    for k in &c.classes {
        let shortfall = vs * k.mass_fraction - k.particles as f64 * sphere_volume(k.diameter);
        assert!(shortfall >= 0.0 && shortfall < sphere_volume(k.diameter));
    }
}

#[test]
fn a_total_particle_count_is_shared_by_mass_fraction_over_particle_volume() {
    // 1000 particles fill only 0.37 of the specimen: the loose column must be looser.
    let text = USER_GRADATION.replace("solid_fraction = 0.60", "particles = 1000")
        + "[preparation]\nloose_solid_fraction = 0.3\n";
    let c = SpecimenSpec::from_toml_str(&text, "count")
        .unwrap()
        .counts()
        .unwrap();
    let n: Vec<u64> = c.classes.iter().map(|k| k.particles).collect();
    // Weights 0.2/1, 0.5/8, 0.3/27 (d in cm): 730.96, 228.43, 40.61; the two units left
    // by the floors go to the largest remainders (0.96, 0.61).
    assert_eq!(n, [731, 228, 41]);
    assert_eq!(c.particles, 1000);
}

#[test]
fn exact_scaling_changes_only_the_penalty_by_the_scale_law() {
    for p in PRESETS.iter().filter(|p| p.exact_scaling) {
        let exact = Preset::find(p.name).unwrap().spec().simulated().unwrap();
        let plain_name = p.name.trim_end_matches('s');
        let plain = Preset::find(plain_name)
            .unwrap()
            .spec()
            .simulated()
            .unwrap();
        let law = ScaleLaw::exact(p.coarse_graining).unwrap();
        let factor = law.factor_of("penalty_stiffness").unwrap();
        assert_eq!(exact.contact.normal_penalty, 1.8e11 * factor, "{}", p.name);
        assert_eq!(exact.scaled.len(), 1, "{}: {:?}", p.name, exact.scaled);
        assert_eq!(exact.scaled[0].0, "contact.normal_penalty");
        let mut same = exact.clone();
        same.contact.normal_penalty = plain.contact.normal_penalty;
        same.scaled.clear();
        assert_eq!(
            same, plain,
            "{}: nothing else differs from {plain_name}",
            p.name
        );
    }
    let e2s = Preset::find("E2s").unwrap().spec().simulated().unwrap();
    assert_eq!(e2s.contact.normal_penalty, 0.9e11);
}

#[test]
fn default_loading_velocity_keeps_the_coarsest_member_at_inertial_number_1e_3() {
    // Both paper series end at 60 mm particles (E4/E4s, B3/B3s): their inertial number is
    // 1e-3 and every member of the series shares the velocity.
    let e4s = Preset::find("E4s").unwrap().spec();
    let v = e4s.loading_velocity();
    let inertial = v / e4s.height * 0.060 * (2650.0f64 / 0.8e6).sqrt();
    assert!((inertial - 1e-3).abs() < 1e-15, "{inertial}");
    assert!((e4s.inertial_number() - 1e-3).abs() < 1e-15);
    for name in ["E1", "E2", "E3", "E4", "B1", "B2s", "B3"] {
        let spec = Preset::find(name).unwrap().spec();
        assert_eq!(spec.loading_velocity(), v, "{name}");
        assert!(spec.inertial_number() <= 1e-3 * (1.0 + 1e-12), "{name}");
    }
    // E1 (15 mm) runs four times slower in inertial number.
    let e1 = Preset::find("E1").unwrap().spec();
    assert!((e1.inertial_number() - 0.25e-3).abs() < 1e-15);
    // A user specimen without series_size uses its own largest simulated size.
    let mut own = e4s.clone();
    own.test.series_size = None;
    own.coarse_graining = 2.0;
    assert!((own.inertial_number() - 1e-3).abs() < 1e-15);
}

#[test]
fn bad_test_settings_are_refused_with_one_line_naming_the_key() {
    let base =
        "diameter = 0.3\nheight = 0.6\ngradation = [{ size = 0.015, mass_fraction = 1.0 }]\n";
    for (extra, key) in [
        ("confining_pressure = -1e5\n", "confining_pressure"),
        ("[test]\ntarget_strain = 0.7\n", "test.target_strain"),
        ("[test]\ntarget_strain = 0.0\n", "test.target_strain"),
        ("[test]\noutput_strain = 0.2\n", "test.output_strain"),
        ("[test]\ninertial_number = 0\n", "test.inertial_number"),
        ("[test]\nservo_band = 2\n", "test.servo_band"),
        ("[test]\ndt_safety = 1.5\n", "test.dt_safety"),
        ("[test]\ndt_safety = 0\n", "test.dt_safety"),
        ("[contact]\ndepth_limit = -0.001\n", "contact.depth_limit"),
        ("[test]\nunknown = 1\n", "test"),
        (
            "[membrane]\npoisson_ratio = 0.6\n",
            "membrane.poisson_ratio",
        ),
        (
            "[membrane]\ndivisions_around = 0\n",
            "membrane.divisions_around",
        ),
        ("[membrane]\ndamping = -1\n", "membrane.damping"),
    ] {
        let text = format!("{base}{extra}");
        let e = SpecimenSpec::from_toml_str(&text, "t.toml")
            .unwrap_err()
            .to_string();
        assert!(!e.contains('\n'), "{e}");
        assert!(e.contains(key), "{key}: {e}");
    }
    let e = SpecimenSpec::from_toml_str("height = 0.6\n", "t.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("diameter"), "{e}");
}

#[test]
fn the_quick_specimen_is_valid_and_test_settings_do_not_change_the_preparation() {
    let quick = fdem_triaxial::quick_spec();
    assert_eq!(quick.name, "quick");
    let mut other = quick.clone();
    other.test.target_strain = 0.1;
    other.membrane.youngs_modulus = 1e6;
    other.loading_velocity = Some(0.1);
    assert_eq!(quick.preparation_key(), other.preparation_key());
    other.seed += 1;
    assert_ne!(quick.preparation_key(), other.preparation_key());
    // A default given explicitly is the same preparation (files written before a default
    // became model-dependent name it).
    let mut implicit = quick.clone();
    implicit.preparation.max_overlap = None;
    let mut explicit = quick.clone();
    explicit.preparation.max_overlap = Some(fdem_triaxial::MAX_OVERLAP_DEFORMABLE);
    assert_eq!(implicit.preparation_key(), explicit.preparation_key());
    explicit.preparation.max_overlap = Some(fdem_triaxial::MAX_OVERLAP_RIGID);
    assert_ne!(implicit.preparation_key(), explicit.preparation_key());
}

fn refused(text: &str) -> (String, String) {
    match SpecimenSpec::from_toml_str(text, "bad.toml") {
        Err(e @ TriaxialError::Definition { .. }) => {
            let TriaxialError::Definition { ref key, .. } = e else {
                unreachable!()
            };
            let message = e.to_string();
            assert!(!message.contains('\n'), "one line: {message}");
            (key.clone(), message)
        }
        other => panic!("expected a definition error, got {other:?}"),
    }
}

const SMALL: &str = r#"
diameter = 0.104
height = 0.06
solid_fraction = 0.5
gradation = [{ size = 0.02, mass_fraction = 1.0 }]
"#;

#[test]
fn bad_definitions_are_refused_with_one_line_naming_the_key() {
    assert!(SpecimenSpec::from_toml_str(SMALL, "ok").is_ok());
    let cases: &[(&str, &str, &str)] = &[
        ("solid_fraction = 0.5", "particles = 4000", "height"),
        ("size = 0.02", "size = 0.2", "gradation[0].size"),
        ("size = 0.02", "size = -0.02", "gradation[0].size"),
        (
            "gradation = [{ size = 0.02, mass_fraction = 1.0 }]",
            "gradation = [{ size = 0.02, mass_fraction = 0.5 }, { size = 0.01, mass_fraction = 0.4 }]",
            "gradation",
        ),
        (
            "solid_fraction = 0.5",
            "solid_fraction = 0.8",
            "solid_fraction",
        ),
        (
            "height = 0.06",
            "height = 0.06\nmembrane_thickness = 0.06",
            "membrane_thickness",
        ),
        ("height = 0.06", "height = 0.06\nheigth = 1.0", "heigth"),
        (
            "height = 0.06",
            "height = 0.06\ncoarse_graining = 6.0",
            "gradation[0].size",
        ),
        (
            "solid_fraction = 0.5",
            "solid_fraction = 0.5\nparticles = 10",
            "particles",
        ),
        (
            "gradation = [{ size = 0.02, mass_fraction = 1.0 }]",
            "gradation = [{ size = 0.02, mass_fraction = 0.9999 }, { size = 0.05, mass_fraction = 0.0001 }]",
            "gradation[1].mass_fraction",
        ),
    ];
    for (from, to, key) in cases {
        let text = SMALL.replace(from, to);
        assert_ne!(text, SMALL);
        let (got, message) = refused(&text);
        assert_eq!(&got, key, "{message}");
        assert!(message.starts_with("bad.toml"), "{message}");
    }
    // A value error carries its line.
    let (_, message) = refused(&SMALL.replace("size = 0.02", "size = -0.02"));
    assert!(message.starts_with("bad.toml:5:"), "{message}");
}

#[test]
fn refused_definitions_do_no_work() {
    use fdem_triaxial::{Observer, Phase, prepare};
    struct Record(Vec<Phase>);
    impl Observer for Record {
        fn phase(&mut self, phase: Phase, _: u64) {
            self.0.push(phase);
        }
    }
    let mut spec = SpecimenSpec::from_toml_str(SMALL, "ok").unwrap();
    spec.gradation[0].mass_fraction = 0.7;
    let mut record = Record(Vec::new());
    let err = prepare(&spec, &mut record).unwrap_err();
    assert!(matches!(err, TriaxialError::Definition { ref key, .. } if key == "gradation"));
    assert!(record.0.is_empty());
}

#[test]
fn presets_round_trip_through_toml_exactly() {
    for p in PRESETS {
        let spec = p.spec();
        let text = spec.to_toml_string().unwrap();
        assert_eq!(SpecimenSpec::from_toml_str(&text, p.name).unwrap(), spec);
    }
}

fn placement_of(
    spec: &SpecimenSpec,
    loose: f64,
) -> (Vec<fdem_triaxial::PlacedParticle>, Column, f64) {
    let c = spec.counts().unwrap();
    let diameters = c.diameters();
    let height = c.solid_volume / (loose * spec.inner_area());
    let column = Column {
        radius: spec.inner_radius(),
        bottom: 0.0,
        top: height,
    };
    let d_min = c
        .classes
        .iter()
        .map(|k| k.diameter)
        .fold(f64::INFINITY, f64::min);
    let clearance = 0.02 * d_min;
    let placed = place_spheres(&diameters, &column, clearance, spec.seed).unwrap();
    (placed, column, clearance)
}

fn assert_valid_placement(spec: &SpecimenSpec, loose: f64) {
    let (placed, column, clearance) = placement_of(spec, loose);
    let c = spec.counts().unwrap();
    assert_eq!(placed.len() as u64, c.particles);
    // No overlaps: every pair, brute force.
    for (i, a) in placed.iter().enumerate() {
        for b in &placed[i + 1..] {
            let d2: f64 = (0..3).map(|k| (a.center[k] - b.center[k]).powi(2)).sum();
            let reach = 0.5 * (a.diameter + b.diameter) + clearance;
            assert!(
                d2 >= reach * reach * (1.0 - 1e-12),
                "{}: overlap",
                spec.name
            );
        }
    }
    // Inside the cylinder.
    for p in &placed {
        let r = 0.5 * p.diameter;
        let rho = (p.center[0].powi(2) + p.center[1].powi(2)).sqrt();
        assert!(rho + r <= column.radius * (1.0 + 1e-12));
        assert!(p.center[2] - r >= column.bottom && p.center[2] + r <= column.top);
        let norm: f64 = p.orientation.iter().map(|q| q * q).sum();
        assert!((norm - 1.0).abs() < 1e-14);
    }
    // Largest first, and each diameter's particles along the Morton curve of their
    // centres (neighbours in space near each other in the body order).
    assert!(placed.windows(2).all(|w| w[0].diameter >= w[1].diameter));
    for group in placed.chunk_by(|a, b| a.diameter == b.diameter) {
        let centres: Vec<[f64; 3]> = group.iter().map(|p| p.center).collect();
        let codes = fdem_core::space_order::morton_codes(&centres);
        assert!(codes.is_sorted(), "{}: not in space order", spec.name);
    }
    // Mass per class within one particle's mass of its share (density cancels).
    let solid = spec.requested_solid_fraction().unwrap() * spec.inner_volume();
    for (i, k) in c.classes.iter().enumerate() {
        let placed_volume: f64 = placed
            .iter()
            .filter(|p| p.class == i)
            .map(|p| sphere_volume(p.diameter))
            .sum();
        let shortfall = solid * k.mass_fraction - placed_volume;
        assert!(
            shortfall >= -1e-12 * solid && shortfall < sphere_volume(k.diameter),
            "{}",
            spec.name
        );
    }
}

#[test]
fn placement_of_the_paper_specimens_has_no_overlap_and_the_requested_fractions() {
    for name in ["E1", "E3", "B2"] {
        assert_valid_placement(&Preset::find(name).unwrap().spec(), 0.25);
    }
    let spec = SpecimenSpec::from_toml_str(USER_GRADATION, "doc example").unwrap();
    assert_valid_placement(&spec, 0.25);
}

#[test]
fn placement_is_reproducible_for_a_seed() {
    let mut spec = Preset::find("E3").unwrap().spec();
    let (a, _, _) = placement_of(&spec, 0.25);
    let (b, _, _) = placement_of(&spec, 0.25);
    assert_eq!(a, b);
    spec.seed = 2;
    let (c, _, _) = placement_of(&spec, 0.25);
    assert_ne!(a, c);
}

#[test]
fn a_column_too_full_is_reported_not_forced() {
    let spec = Preset::find("E3").unwrap().spec();
    let c = spec.counts().unwrap();
    let diameters = vec![(0.045, 0); c.particles as usize];
    // Solid fraction 0.6 is far beyond random sequential placement (about 0.38).
    let column = Column {
        radius: spec.inner_radius(),
        bottom: 0.0,
        top: c.solid_volume / (0.6 * spec.inner_area()),
    };
    assert!(place_spheres(&diameters, &column, 1e-3, 1).is_err());
}

#[test]
fn random_rotations_are_unit_and_unbiased() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let n = 20_000;
    let mut mean = [0.0; 3];
    for _ in 0..n {
        let q = random_rotation(&mut rng);
        let norm: f64 = q.iter().map(|c| c * c).sum();
        assert!((norm - 1.0).abs() < 1e-14);
        // The rotated z axis: third column of the rotation matrix.
        let [w, x, y, z] = q;
        let axis = [
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ];
        for k in 0..3 {
            mean[k] += axis[k] / n as f64;
        }
    }
    // Uniform directions: each mean component ~ N(0, 1/(3n)); 5 sigma = 0.02.
    assert!(mean.iter().all(|m| m.abs() < 0.02), "{mean:?}");
}

/// The memory estimate grows with the mesh and refuses what the available memory cannot
/// hold, before any work, naming both figures: E1 at level 4 (about 194 M nodes with
/// quadratic elements) needs tens of GB; E4s fits in 8 GB; the rigid E1 (level 1) needs
/// less than 1 GB (a whole-process peak of 561 MB was measured, docs/PERFORMANCE.md).
#[test]
fn memory_estimates_refuse_what_cannot_fit() {
    let mut e1 = Preset::find("E1").unwrap().spec();
    e1.mesh.level = 4;
    let counts = e1.counts().unwrap();
    let need = counts.memory_estimate(true);
    assert!(need > 20_000_000_000, "{need}");
    let e = fdem_triaxial::check_memory(&e1, &counts, Some(8_000_000_000)).unwrap_err();
    assert!(e.to_string().contains("GB"), "{e}");
    assert!(fdem_triaxial::check_memory(&e1, &counts, None).is_ok());
    let e4s = Preset::find("E4s").unwrap().spec();
    let c = e4s.counts().unwrap();
    assert!(fdem_triaxial::check_memory(&e4s, &c, Some(8_000_000_000)).is_ok());
    let mut rigid = Preset::find("E1").unwrap().spec();
    rigid.model = fdem_solver::ParticleModel::Rigid;
    rigid.mesh.order = fdem_mesh::ElementOrder::Linear;
    let c = rigid.counts().unwrap();
    let estimate = c.memory_estimate(false);
    assert!(
        estimate > 561_000_000 && estimate < 1_000_000_000,
        "{estimate}"
    );
}
