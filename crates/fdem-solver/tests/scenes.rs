//! Scene loading and running: every rejection names its key and line, nothing panics,
//! outputs are complete and consistent, and a single free body obeys exact scaling.

// Component loops over x, y, z read best with an index.
#![allow(clippy::needless_range_loop)]

use fdem_solver::{RunOptions, Scene, Silent, SolverError, run};
use proptest::prelude::*;
use std::sync::atomic::AtomicBool;

const GOOD: &str = r#"[simulation]
duration = 2.0e-5
output_interval = 5.0e-6

[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2

[[particle]]
diameter = 0.015
center = [0.0, 0.0, 0.0]
velocity = [0.5, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 100.0]
orientation = [1.0, 0.0, 0.0, 0.0]
mesh = { level = 1, order = "linear" }
"#;

fn rejection(text: &str) -> (String, usize, String) {
    match Scene::from_toml_str(text, "scene.toml") {
        Err(SolverError::Scene {
            key, line, message, ..
        }) => (key, line, message),
        Err(other) => panic!("unexpected error kind: {other}"),
        Ok(_) => panic!("accepted:\n{text}"),
    }
}

#[test]
fn the_documented_example_loads() {
    let scene = Scene::from_toml_str(GOOD, "scene.toml").unwrap();
    assert_eq!(scene.particles.len(), 1);
    assert_eq!(scene.output_interval(), 5.0e-6);
}

#[test]
fn each_kind_of_mistake_names_its_key_and_line() {
    let cases: &[(&str, &str, &str, usize)] = &[
        (
            "duration = 2.0e-5",
            "duration = -1.0",
            "simulation.duration",
            2,
        ),
        (
            "duration = 2.0e-5",
            "duration = \"long\"",
            "simulation.duration",
            2,
        ),
        (
            "duration = 2.0e-5",
            "duratoin = 2.0e-5",
            "simulation.duratoin",
            2,
        ),
        (
            "poisson_ratio = 0.2",
            "poisson_ratio = 0.5",
            "material.poisson_ratio",
            8,
        ),
        (
            "youngs_modulus = 40.0e9",
            "youngs_modulus = 0.0",
            "material.youngs_modulus",
            7,
        ),
        (
            "diameter = 0.015",
            "diameter = -0.015",
            "particle[0].diameter",
            11,
        ),
        (
            "center = [0.0, 0.0, 0.0]",
            "center = [0.0, 0.0]",
            "particle[0].center",
            12,
        ),
        (
            "center = [0.0, 0.0, 0.0]",
            "center = [0.0, 0.0, 0.0, 99.0]",
            "particle[0].center",
            12,
        ),
        (
            "orientation = [1.0, 0.0, 0.0, 0.0]",
            "orientation = [1.0, 0.0, 0.0, 0.0, 0.0]",
            "particle[0].orientation",
            15,
        ),
        (
            "orientation = [1.0, 0.0, 0.0, 0.0]",
            "orientation = [1.0, 1.0, 0.0, 0.0]",
            "particle[0].orientation",
            15,
        ),
        ("level = 1", "level = 9", "particle[0].mesh.level", 16),
        (
            "level = 1",
            "level = 1, shells = 0",
            "particle[0].mesh.shells",
            16,
        ),
        (
            "level = 1",
            "level = 1, shells = 9",
            "particle[0].mesh.shells",
            16,
        ),
        (
            "level = 1",
            "level = 1, axes = [1.0, 0.0, 0.5]",
            "particle[0].mesh.axes",
            16,
        ),
        (
            "order = \"linear\"",
            "order = \"cubic\"",
            "particle[0].mesh.order",
            16,
        ),
        (
            "output_interval = 5.0e-6",
            "output_interval = 5.0e-6\ndt_safety = 1.5",
            "simulation.dt_safety",
            4,
        ),
    ];
    for &(from, to, key, line) in cases {
        assert!(GOOD.contains(from), "{from}");
        let text = GOOD.replacen(from, to, 1);
        let (k, l, message) = rejection(&text);
        assert_eq!(k, key, "{to}: {message}");
        assert_eq!(l, line, "{to}: {message}");
        assert!(!message.is_empty());
    }
    // A missing required key names its table.
    let (k, _, m) = rejection(&GOOD.replace("duration = 2.0e-5\n", ""));
    assert_eq!(k, "simulation");
    assert!(m.contains("duration"), "{m}");
    // No particles at all.
    let no_particles = &GOOD[..GOOD.find("[[particle]]").unwrap()];
    assert_eq!(rejection(no_particles).0, "particle");
}

#[test]
fn a_failed_load_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let scene_path = dir.path().join("bad.toml");
    std::fs::write(
        &scene_path,
        GOOD.replace("diameter = 0.015", "diameter = 0.0"),
    )
    .unwrap();
    assert!(Scene::load(&scene_path).is_err());
    assert!(!out.exists());
}

fn mutate(text: &str, pos: usize, kind: u8, byte: u8) -> String {
    let mut bytes = text.as_bytes().to_vec();
    if bytes.is_empty() {
        return char::from(byte).to_string();
    }
    let pos = pos % bytes.len();
    match kind % 4 {
        0 => {
            bytes.remove(pos);
        }
        1 => bytes.insert(pos, byte),
        2 => bytes[pos] = byte,
        _ => bytes.truncate(pos),
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Random edits of a valid scene: the loader never panics, and every rejection is a
    /// scene error that names a key (or `<document>` for syntax errors).
    #[test]
    fn malformed_scenes_never_panic(edits in proptest::collection::vec((any::<usize>(), any::<u8>(), 32u8..127), 1..4)) {
        let mut text = GOOD.to_string();
        for (pos, kind, byte) in edits {
            text = mutate(&text, pos, kind, byte);
        }
        match Scene::from_toml_str(&text, "scene.toml") {
            Ok(scene) => { let _ = scene.time_step(); }
            Err(SolverError::Scene { key, message, .. }) => {
                prop_assert!(!key.is_empty());
                prop_assert!(!message.is_empty());
            }
            Err(other) => prop_assert!(false, "not a scene error: {}", other),
        }
    }

    /// Arbitrary text is refused cleanly.
    #[test]
    fn random_text_never_panics(text in "\\PC{0,200}") {
        let _ = Scene::from_toml_str(&text, "scene.toml");
    }
}

fn read_csv(path: &std::path::Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn a_run_writes_complete_consistent_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::from_toml_str(GOOD, "scene.toml").unwrap();
    let options = RunOptions {
        out_dir: dir.path().to_path_buf(),
        vtk: true,
        contacts: true,
    };
    let summary = run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
    assert_eq!(summary.status, "completed");
    assert!(summary.time >= 2.0e-5 - 1e-18);
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    for expected in [
        "energy.csv",
        "bodies.csv",
        "summary.json",
        "frames.pvd",
        "frames",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing in {names:?}"
        );
    }
    assert!(!names.iter().any(|n| n.ends_with(".part")), "{names:?}");
    let energy = read_csv(&dir.path().join("energy.csv"));
    assert_eq!(energy.len(), summary.outputs);
    assert_eq!(energy[0][0], 0.0);
    // Free flight at 0.5 m/s: the centroid moves by v t (1e-9 relative: the elastic
    // vibration excited by the spin displaces the centroid by far less).
    let bodies = read_csv(&dir.path().join("bodies.csv"));
    let last = bodies.last().unwrap();
    assert!(
        (last[2] - 0.5 * last[0]).abs() < 1e-9 * 0.5 * last[0].max(1e-30) + 1e-15,
        "{last:?}"
    );
    assert!((last[10] - 100.0).abs() < 1e-6 * 100.0, "spin {}", last[10]);
    let frames = std::fs::read_dir(dir.path().join("frames"))
        .unwrap()
        .count();
    assert_eq!(frames, summary.outputs);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(json["status"], "completed");
    assert!(
        json["dt_bound_source"]
            .as_str()
            .unwrap()
            .starts_with("elastic")
    );
}

/// Records the run identifier of the plan.
#[derive(Default)]
struct Named(Option<String>);

impl fdem_solver::Observer for Named {
    fn start(&mut self, plan: &fdem_solver::RunPlan) {
        self.0 = Some(plan.run_id.clone());
    }
}

/// Every run is named: the identifier (UTC start and the hash of the scene as parsed) is
/// in the plan announced before the first step and in `summary.json`; the CSV files stay
/// plain. The same scene gives the same hash, another scene another.
#[test]
fn every_run_is_named_in_its_summary() {
    let dir = tempfile::tempdir().unwrap();
    let named = |text: &str, out: &str| {
        let scene = Scene::from_toml_str(text, "scene.toml").unwrap();
        let options = RunOptions {
            out_dir: dir.path().join(out),
            vtk: false,
            contacts: false,
        };
        let mut observer = Named::default();
        let summary = run(&scene, &options, &mut observer, &AtomicBool::new(false)).unwrap();
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(options.out_dir.join("summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(observer.0.as_deref(), Some(summary.run_id.as_str()));
        assert_eq!(json["run_id"], summary.run_id.as_str());
        let energy = std::fs::read_to_string(options.out_dir.join("energy.csv")).unwrap();
        assert!(energy.starts_with("time,kinetic,"), "{energy}");
        (scene, summary.run_id)
    };
    let seconds = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs() as i64
    };
    let before = fdem_core::run_id::utc_stamp(seconds());
    let (scene, id) = named(GOOD, "a");
    let after = fdem_core::run_id::utc_stamp(seconds());
    // `YYYYMMDDTHHMMSSZ-hhhhhhhh`.
    let (stamp, hash) = id.split_once('-').unwrap();
    assert!(before.as_str() <= stamp && stamp <= after.as_str(), "{id}");
    let definition = scene.to_toml_string().unwrap();
    let expected = fdem_core::hash::Fnv1a::of(definition.as_bytes()) >> 32;
    assert_eq!(hash, format!("{expected:08x}"));
    // Comments and layout are not the definition; a value is.
    let (_, same) = named(&format!("# a comment\n{GOOD}"), "b");
    assert_eq!(same.split_once('-').unwrap().1, hash);
    let (_, other) = named(&GOOD.replace("0.015", "0.016"), "c");
    assert_ne!(other.split_once('-').unwrap().1, hash);
}

/// Exact scaling of one free body (docs/MODEL.md section 4): geometry x h, time and dt x h,
/// velocities x 1, angular velocities x 1/h. Positions must scale by h and velocities
/// by 1 at corresponding times, to round-off (1e-9 relative, far above the 1e-16
/// per-operation round-off accumulated over some hundred steps, far below any physical
/// difference: a wrong factor anywhere changes the answer at order 1).
#[test]
fn a_free_body_obeys_exact_scaling() {
    let base = Scene::from_toml_str(GOOD, "scene.toml").unwrap();
    for h in [0.25, 3.0, 7.5] {
        let mut scaled = base.clone();
        let s = &mut scaled.simulation;
        s.duration *= h;
        s.output_interval = s.output_interval.map(|t| t * h);
        let p = &mut scaled.particles[0];
        p.diameter *= h;
        p.center = p.center.map(|x| x * h);
        p.angular_velocity = p.angular_velocity.map(|w| w.map(|x| x / h));
        let mut contact = scaled.contact_section();
        contact.normal_penalty /= h;
        scaled.contact = Some(contact);
        let (mut a, mut b) = (base.build().unwrap(), scaled.build().unwrap());
        assert!(
            (b.dt() / (a.dt() * h) - 1.0).abs() < 1e-12,
            "automatic dt must scale by h"
        );
        b.set_dt(a.dt() * h).unwrap();
        for _ in 0..300 {
            a.advance().unwrap();
            b.advance().unwrap();
        }
        let size = 0.015;
        for (xa, xb) in a.state().positions.iter().zip(&b.state().positions) {
            for k in 0..3 {
                assert!((xb[k] - h * xa[k]).abs() < 1e-9 * h * size, "h = {h}");
            }
        }
        for (va, vb) in a.state().velocities.iter().zip(&b.state().velocities) {
            for k in 0..3 {
                assert!((vb[k] - va[k]).abs() < 1e-9, "h = {h}");
            }
        }
        let (ea, eb) = (a.energy(), b.energy());
        assert!((eb.kinetic / (h.powi(3) * ea.kinetic) - 1.0).abs() < 1e-9);
    }
}

/// Runs the scene `text` with VTK frames into a new temporary directory.
fn run_with_frames(text: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::from_toml_str(text, "frames.toml").unwrap();
    let options = RunOptions {
        out_dir: dir.path().to_path_buf(),
        vtk: true,
        contacts: false,
    };
    run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
    dir
}

/// A scene of rigid particles only writes its frames as the particles' surface
/// triangles (VTK_TRIANGLE), one `body` value per triangle, and no stress.
#[test]
fn rigid_particles_are_written_as_their_surface_triangles() {
    let text = r#"
[simulation]
duration = 2.0e-4
dt_safety = 0.4
output_interval = 1.0e-4
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
model = "rigid"
[[particle]]
diameter = 0.01
center = [0.0102, 0.0, 0.0]
velocity = [-1.0, 0.0, 0.0]
model = "rigid"
"#;
    let dir = run_with_frames(text);
    let vtu = std::fs::read_to_string(dir.path().join("frames/frame_000000.vtu")).unwrap();
    // Level 1: 42 surface nodes and 80 triangles per particle.
    assert!(vtu.contains("NumberOfPoints=\"84\""), "{}", &vtu[..300]);
    assert!(vtu.contains("NumberOfCells=\"160\""), "{}", &vtu[..300]);
    assert!(!vtu.contains("Name=\"stress\""));
}

/// A scene that mixes a linear, a quadratic and a rigid particle writes one frame of
/// mixed cells: the two particles' tetrahedra (VTK_TETRA, VTK_QUADRATIC_TETRA) and the
/// rigid particle's surface triangles, with a stress per cell (zero on the triangles).
#[test]
fn a_mixed_scene_is_written_as_tetrahedra_of_both_orders_and_rigid_triangles() {
    let text = r#"
[simulation]
duration = 1.0e-5
dt_safety = 0.4
output_interval = 1.0e-5
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[[particle]]
diameter = 0.01
center = [0.0, 0.0, 0.0]
mesh = { level = 1, order = "linear" }
[[particle]]
diameter = 0.01
center = [0.0102, 0.0, 0.0]
mesh = { level = 1, order = "quadratic" }
[[particle]]
diameter = 0.01
center = [0.0, 0.0102, 0.0]
model = "rigid"
"#;
    let dir = run_with_frames(text);
    let vtk = vtkio::Vtk::import(dir.path().join("frames/frame_000000.vtu")).unwrap();
    let vtkio::model::DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid");
    };
    let Some(vtkio::model::Piece::Inline(piece)) = pieces.into_iter().next() else {
        panic!("no inline piece");
    };
    use vtkio::model::CellType;
    let types = &piece.cells.types;
    // Level 1: 80 tetrahedra per deformable particle, 80 surface triangles per rigid one.
    let count = |t: CellType| types.iter().filter(|&&c| c == t).count();
    assert_eq!(count(CellType::Tetra), 80);
    assert_eq!(count(CellType::QuadraticTetra), 80);
    assert_eq!(count(CellType::Triangle), 80);
    // 43 linear and 205 quadratic element nodes, and the rigid particle's 42 surface nodes.
    assert_eq!(piece.num_points(), 43 + 205 + 42);
    let stress = piece
        .data
        .cell
        .iter()
        .find(|a| a.name() == "stress")
        .expect("a stress field");
    let vtkio::model::Attribute::DataArray(array) = stress else {
        panic!("stress is not a data array");
    };
    let values: Vec<f64> = array.data.clone().into_vec().unwrap();
    assert_eq!(values.len(), 9 * 240);
    assert!(values[9 * 160..].iter().all(|&v| v == 0.0));
}

/// Durations and steps at the ends of the floating-point range: a duration far below
/// one step (with its default output interval below the time's resolution) runs its one
/// step and returns; a plan of more than `MAX_STEPS` steps is refused before any output
/// is created; more than `MAX_OUTPUTS` outputs are refused at their key.
#[test]
fn extreme_durations_and_steps_end_or_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let options = |name: &str| RunOptions {
        out_dir: dir.path().join(name),
        vtk: false,
        contacts: false,
    };
    let tiny = GOOD
        .replace("duration = 2.0e-5", "duration = 1.0e-300")
        .replace("output_interval = 5.0e-6\n", "");
    let scene = Scene::from_toml_str(&tiny, "tiny.toml").unwrap();
    let summary = run(
        &scene,
        &options("tiny"),
        &mut Silent,
        &AtomicBool::new(false),
    )
    .unwrap();
    assert_eq!(summary.steps, 1);
    let many = GOOD.replace("output_interval = 5.0e-6", "dt = 1.0e-300");
    let scene = Scene::from_toml_str(&many, "many.toml").unwrap();
    let e = run(
        &scene,
        &options("many"),
        &mut Silent,
        &AtomicBool::new(false),
    )
    .unwrap_err();
    assert!(e.to_string().contains("more than"), "{e}");
    assert!(!dir.path().join("many").exists());
    let outputs = GOOD.replace("output_interval = 5.0e-6", "output_interval = 1.0e-12");
    let (key, _, message) = rejection(&outputs);
    assert_eq!(key, "simulation.output_interval", "{message}");
}

/// A run owns its directory: a shorter run into the directory of a longer one leaves
/// only its own frames, and files that are not a run's output stay.
#[test]
fn a_shorter_run_leaves_no_frames_of_an_earlier_one() {
    let dir = tempfile::tempdir().unwrap();
    let options = RunOptions {
        out_dir: dir.path().to_path_buf(),
        vtk: true,
        contacts: false,
    };
    let count = |folder: &str| std::fs::read_dir(dir.path().join(folder)).unwrap().count();
    let long = GOOD.replace("duration = 2.0e-5", "duration = 4.0e-5");
    let scene = Scene::from_toml_str(&long, "long.toml").unwrap();
    run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
    let frames = count("frames");
    std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
    let scene = Scene::from_toml_str(GOOD, "short.toml").unwrap();
    let short = run(&scene, &options, &mut Silent, &AtomicBool::new(false)).unwrap();
    assert!(frames > short.outputs, "{frames} frames");
    assert_eq!(count("frames"), short.outputs);
    assert_eq!(
        std::fs::read_to_string(dir.path().join("notes.txt")).unwrap(),
        "mine"
    );
}

/// Impossible starts are refused before the run, naming the bodies: two particles at one
/// centre or half inside each other, a particle behind a wall or cut by one. A slight
/// overlap (a contact) is accepted, and `allow_initial_overlap = true` accepts them all.
#[test]
fn impossible_starting_geometry_is_refused_naming_the_bodies() {
    let second =
        |x: f64| format!("{GOOD}\n[[particle]]\ndiameter = 0.015\ncenter = [{x}, 0.0, 0.0]\n");
    let wall = |z: f64| {
        format!(
            "{GOOD}\n[[wall]]\ntype = \"plane\"\npoint = [0.0, 0.0, {z}]\nnormal = [0.0, 0.0, 1.0]\n"
        )
    };
    let refusal = |text: &str| match Scene::from_toml_str(text, "s.toml").unwrap().build() {
        Ok(_) => None,
        Err(e) => Some(e.to_string()),
    };
    for (text, needle) in [
        (second(0.0), "particle[0] and particle[1]"),
        (second(0.0075), "particle[0] and particle[1]"),
        (wall(0.01), "behind wall[0]"),
        (wall(-0.003), "cut by wall[0]"),
    ] {
        let message = refusal(&text).unwrap_or_else(|| panic!("accepted: {needle}"));
        assert!(message.contains(needle), "{message}");
        assert!(message.contains("allow_initial_overlap"), "{message}");
        let allowed = text.replace(
            "output_interval = 5.0e-6",
            "output_interval = 5.0e-6\nallow_initial_overlap = true",
        );
        assert_eq!(refusal(&allowed), None, "{needle}");
    }
    // Touching (the inscribed polyhedra just apart) and resting on a wall are fine.
    assert_eq!(refusal(&second(0.0149)), None);
    assert_eq!(refusal(&wall(-0.0075)), None);
}

/// Extreme values in messages are printed in exponent form, not as hundreds of digits.
#[test]
fn extreme_values_are_printed_short_in_messages() {
    for (from, to, shown) in [
        ("diameter = 0.015", "diameter = -1e-300", "-1e-300"),
        ("poisson_ratio = 0.2", "poisson_ratio = -1e300", "-1e300"),
        (
            "output_interval = 5.0e-6",
            "output_interval = 1e300",
            "1e300 s is longer than the duration",
        ),
    ] {
        let (_, _, message) = rejection(&GOOD.replacen(from, to, 1));
        assert!(message.contains(shown), "{message}");
        assert!(message.len() < 200, "{message}");
    }
}

/// Values across the whole f64 range, as TOML spells them.
const EXTREMES: &[&str] = &[
    "0.0", "-0.0", "5e-324", "1e-308", "1e-300", "1e-12", "1.0", "-1.0", "1e12", "1e300",
    "1.7e308", "nan", "inf", "-inf",
];

/// The numeric fields of a two-particle scene with a wall, as `(table line, key)`.
const FIELDS: &[&str] = &[
    "duration",
    "dt",
    "output_interval",
    "density",
    "youngs_modulus",
    "poisson_ratio",
    "diameter",
    "cx",
    "vx",
    "normal_penalty",
    "friction",
    "damping",
    "margin",
    "depth_limit",
    "wall_z",
    "wall_vz",
];

/// The scene with field `k` set to `v` (every other field ordinary).
fn extreme_scene(k: usize, v: &str) -> String {
    let value = |name: &str, ordinary: &str| {
        if FIELDS[k] == name {
            v.to_string()
        } else {
            ordinary.to_string()
        }
    };
    format!(
        "[simulation]\nduration = {}\ndt = {}\noutput_interval = {}\n\
         [material]\ndensity = {}\nyoungs_modulus = {}\npoisson_ratio = {}\n\
         [[particle]]\ndiameter = {}\ncenter = [{}, 0.0, 0.0]\nvelocity = [{}, 0.0, 0.0]\n\
         [[particle]]\ndiameter = 0.015\ncenter = [0.0152, 0.0, 0.0]\n\
         [contact]\nnormal_penalty = {}\nfriction = {}\ndamping = {}\nmargin = {}\ndepth_limit = {}\n\
         [[wall]]\ntype = \"plane\"\npoint = [0.0, 0.0, {}]\nnormal = [0.0, 0.0, 1.0]\nvelocity = [0.0, 0.0, {}]\n",
        value("duration", "2.0e-6"),
        value("dt", "1.0e-8"),
        value("output_interval", "1.0e-6"),
        value("density", "2650.0"),
        value("youngs_modulus", "40.0e9"),
        value("poisson_ratio", "0.2"),
        value("diameter", "0.015"),
        value("cx", "0.0"),
        value("vx", "0.5"),
        value("normal_penalty", "1.8e11"),
        value("friction", "0.3"),
        value("damping", "0.2"),
        value("margin", "0.001"),
        value("depth_limit", "0.001"),
        value("wall_z", "-0.0076"),
        value("wall_vz", "0.0"),
    )
}

/// Every numeric field at every extreme (all 224 combinations): the scene is refused, or
/// it builds and runs its first steps (at most 300), or stops with an error, never
/// panicking, and a run that finishes its steps holds finite positions.
#[test]
fn extreme_values_are_refused_or_run_without_panic() {
    let mut failures = Vec::new();
    for k in 0..FIELDS.len() {
        for value in EXTREMES {
            let text = extreme_scene(k, value);
            let outcome = std::panic::catch_unwind(|| {
                let Ok(scene) = Scene::from_toml_str(&text, "scene.toml") else {
                    return true;
                };
                let Ok(mut sim) = scene.build() else {
                    return true;
                };
                let steps = fdem_solver::step_count(scene.simulation.duration, sim.dt()).min(300);
                for _ in 0..steps {
                    if sim.advance().is_err() {
                        return true;
                    }
                }
                sim.state()
                    .positions
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite())
            });
            match outcome {
                Ok(true) => {}
                Ok(false) => failures.push(format!("{} = {value}: non-finite state", FIELDS[k])),
                Err(_) => failures.push(format!("{} = {value}: panicked", FIELDS[k])),
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Every array of the scene schema at every length from 0 to 5: the scene is accepted
/// only at the array's own length, and otherwise refused with one line naming the key
/// and the length it needs.
#[test]
fn arrays_of_every_length_are_refused_unless_whole() {
    // The scene with its nine arrays given as TOML text, in the order of `keys`.
    let base = |gravity: &str,
                center: &str,
                velocity: &str,
                spin: &str,
                q: &str,
                axes: &str,
                point: &str,
                normal: &str,
                wall_v: &str| {
        format!(
            "[simulation]\nduration = 1.0e-6\ndt = 1.0e-8\ngravity = {gravity}\n\
             [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n\
             [[particle]]\ndiameter = 0.015\ncenter = {center}\nvelocity = {velocity}\n\
             angular_velocity = {spin}\norientation = {q}\n\
             mesh = {{ level = 1, order = \"linear\", axes = {axes} }}\n\
             [contact]\nnormal_penalty = 1.8e11\n\
             [[wall]]\ntype = \"plane\"\npoint = {point}\nnormal = {normal}\nvelocity = {wall_v}\n"
        )
    };
    let whole = [
        "[0.0, 0.0, 0.0]",
        "[0.0, 0.0, 0.0]",
        "[0.0, 0.0, 0.0]",
        "[0.0, 0.0, 0.0]",
        "[1.0, 0.0, 0.0, 0.0]",
        "[1.0, 1.0, 1.0]",
        "[0.0, 0.0, -0.0076]",
        "[0.0, 0.0, 1.0]",
        "[0.0, 0.0, 0.0]",
    ];
    let keys = [
        "gravity",
        "center",
        "velocity",
        "angular_velocity",
        "orientation",
        "axes",
        "point",
        "normal",
        "velocity",
    ];
    let text = |a: &[String]| {
        base(
            &a[0], &a[1], &a[2], &a[3], &a[4], &a[5], &a[6], &a[7], &a[8],
        )
    };
    let ordinary: Vec<String> = whole.iter().map(|s| s.to_string()).collect();
    Scene::from_toml_str(&text(&ordinary), "scene.toml").expect("the ordinary scene is valid");
    for (i, key) in keys.iter().enumerate() {
        let needed = whole[i].matches(',').count() + 1;
        for len in 0..=5 {
            let values: Vec<&str> = (0..len)
                .map(|j| if j == 0 && i == 4 { "1.0" } else { "0.5" })
                .collect();
            let mut arrays = ordinary.clone();
            arrays[i] = format!("[{}]", values.join(", "));
            let result = Scene::from_toml_str(&text(&arrays), "scene.toml");
            if len == needed {
                continue;
            }
            let e = result
                .err()
                .unwrap_or_else(|| panic!("{key} of length {len} accepted"))
                .to_string();
            assert_eq!(e.lines().count(), 1, "{e}");
            assert!(
                e.contains(key) && e.contains(&needed.to_string()),
                "{key}, {len}: {e}"
            );
        }
    }
}
