//! The memory estimate of a scene: it counts what the built model holds, and a run that
//! cannot fit is refused before anything is allocated, in one line with the estimate,
//! what is available and what to change.

use fdem_solver::{RunOptions, Scene, Silent, bytes_text, check_memory, run};
use std::sync::atomic::AtomicBool;

/// A scene of `particles` (each `(mesh, model)`) in a row along x, 20 mm apart, with a
/// floor below them when `wall`.
fn scene(particles: &[(&str, &str)], wall: bool) -> Scene {
    let mut text = String::from(
        "[simulation]\nduration = 1.0e-5\n\
         [material]\ndensity = 2650.0\nyoungs_modulus = 40.0e9\npoisson_ratio = 0.2\n",
    );
    for (i, (mesh, model)) in particles.iter().enumerate() {
        text.push_str(&format!(
            "[[particle]]\ndiameter = 0.015\ncenter = [{}, 0.0, 0.0]\nmesh = {mesh}\nmodel = \"{model}\"\n",
            0.02 * i as f64
        ));
    }
    if wall {
        text.push_str(
            "[[wall]]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.01]\nnormal = [0.0, 0.0, 1.0]\n",
        );
    }
    Scene::from_toml_str(&text, "scene.toml").unwrap()
}

/// `n` particles of the finest mesh a scene may ask for: level 4, quadratic, 8 shells
/// (about 51 MB each).
fn finest(n: usize) -> Scene {
    let mesh = "{ level = 4, order = \"quadratic\", shells = 8 }";
    scene(&vec![(mesh, "deformable"); n], false)
}

fn options(dir: &std::path::Path, vtk: bool, contacts: bool) -> RunOptions {
    RunOptions {
        out_dir: dir.to_path_buf(),
        vtk,
        contacts,
    }
}

/// The counts come from one template per kind of mesh; they are those of the model the
/// scene builds, for deformable and rigid particles, one and several shells, both orders.
#[test]
fn the_estimate_counts_what_the_model_holds() {
    let linear = scene(
        &[
            ("{ level = 1 }", "deformable"),
            ("{ level = 1 }", "deformable"),
            ("{ level = 2, shells = 2 }", "deformable"),
            ("{ level = 2 }", "rigid"),
            ("{ level = 1, axes = [1.0, 0.8, 0.6] }", "rigid"),
        ],
        true,
    );
    let quadratic = scene(
        &[
            ("{ level = 1, order = \"quadratic\" }", "deformable"),
            ("{ level = 0, order = \"quadratic\" }", "rigid"),
        ],
        false,
    );
    let lone = scene(&[("{ level = 1 }", "deformable")], false);
    for s in [&linear, &quadratic, &lone] {
        let size = s.model_size().unwrap();
        let sim = s.build().unwrap();
        assert_eq!(size.particles as usize, sim.bodies().len());
        assert_eq!(size.nodes as usize, sim.state().len());
        assert_eq!(size.elements() as usize, sim.n_elements());
    }
    // Contact data only where the model has contact (a lone particle has none).
    assert_eq!(lone.model_size().unwrap().contact_nodes, 0);
    assert!(linear.model_size().unwrap().contact_nodes > 0);
    let q = quadratic.model_size().unwrap();
    assert_eq!((q.linear_elements, q.quadratic_elements > 0), (0, true));
}

/// 40 particles of the finest mesh (about 2 GB) against 1 GB: refused with the
/// estimate, what is available and what to change, with the outputs named when asked
/// for; a small scene, and any scene where the platform does not say, is accepted.
#[test]
fn a_scene_that_cannot_fit_is_refused_with_its_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let gb = 1_000_000_000;
    let huge = finest(40);
    let need = huge.model_size().unwrap().bytes();
    assert!(need > 2 * gb && need < 3 * gb, "{need}");
    let e = check_memory(&huge, &options(dir.path(), false, false), Some(gb))
        .unwrap_err()
        .to_string();
    assert_eq!(e.lines().count(), 1, "{e}");
    for part in [
        "40 particles with 6247720 nodes and 4505600 elements",
        &format!("need about {}", bytes_text(need)),
        "but 1.0 GB are available",
        "mesh.level",
        "model = \"rigid\"",
    ] {
        assert!(e.contains(part), "{part}: {e}");
    }
    assert!(!e.contains("--vtk"), "{e}");
    let e = check_memory(&huge, &options(dir.path(), true, true), Some(gb))
        .unwrap_err()
        .to_string();
    for part in [
        "for a VTU frame",
        "for a contact snapshot",
        "or run without --vtk and --contacts",
    ] {
        assert!(e.contains(part), "{part}: {e}");
    }
    assert_eq!(
        check_memory(&huge, &options(dir.path(), false, false), None).unwrap(),
        need
    );
    let small = scene(&[("{ level = 1 }", "deformable"); 2], false);
    let estimate = check_memory(&small, &options(dir.path(), true, true), Some(gb)).unwrap();
    assert!(estimate < 100_000_000, "{estimate}");
}

/// A run checks the memory the system reports available before it builds the model or
/// creates its directory (skipped where the platform does not say, or has more than
/// the terabyte asked for).
#[test]
fn a_run_that_cannot_fit_is_refused_before_any_work() {
    let Some(available) = fdem_core::fs::available_memory() else {
        eprintln!("skipped: the platform does not report the memory available");
        return;
    };
    let huge = finest(20_000);
    let need = huge.model_size().unwrap().bytes();
    if need <= available {
        eprintln!("skipped: {available} bytes available, more than the {need} asked for");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let started = std::time::Instant::now();
    let e = run(
        &huge,
        &options(&out, false, false),
        &mut Silent,
        &AtomicBool::new(false),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("are available"), "{e}");
    assert!(!out.exists());
    assert!(started.elapsed().as_secs() < 30);
}
