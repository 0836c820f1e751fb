//! The `auto` particle model: the deflection estimate against its closed forms, its
//! invariance under exact scaling, and its resolution in scenes.

use fdem_solver::{
    DeflectionInputs, ParticleModel, PatchRegime, Scene, deflection_estimate, mean_contact_force,
};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs()
}

/// The paper's particle and law (docs/MODEL.md section 8) with a given node area and force.
fn rock(node_area: f64, contact_force: f64) -> DeflectionInputs {
    DeflectionInputs {
        diameter: 0.015,
        youngs_modulus: 40.0e9,
        poisson_ratio: 0.2,
        normal_penalty: 1.8e11,
        node_area,
        contact_force,
    }
}

/// In the lens regime the overlap returns the force through `f = p_n pi R delta^2 / 2`
/// and the patch is `a^2 = R delta`; in the node regime `delta = f / (p_n A)` over
/// `a = sqrt(A / pi)`; in both the deflection is Boussinesq's flat punch
/// `w = f (1 - nu^2) / (2 a E)` (1e-12). The regime is the larger patch.
#[test]
fn the_estimate_follows_its_closed_forms_in_both_regimes() {
    let pi = std::f64::consts::PI;
    // A tiny node area: the lens covers many nodes.
    let lens = deflection_estimate(rock(1e-9, 200.0), 0.05);
    assert_eq!(lens.regime, PatchRegime::Lens);
    let (r, p_n, f) = (0.0075, 1.8e11, 200.0);
    assert!(close(
        p_n * pi * r * lens.overlap * lens.overlap / 2.0,
        f,
        1e-12
    ));
    assert!(close(
        lens.patch_radius * lens.patch_radius,
        r * lens.overlap,
        1e-12
    ));
    // A large node area (the level-1 surface's): one node carries the force.
    let area = pi * 0.015 * 0.015 / 42.0;
    let node = deflection_estimate(rock(area, 200.0), 0.05);
    assert_eq!(node.regime, PatchRegime::Node);
    assert!(close(node.overlap, f / (p_n * area), 1e-12));
    assert!(close(node.patch_radius, (area / pi).sqrt(), 1e-12));
    for e in [lens, node] {
        let w = f * (1.0 - 0.04) / (2.0 * e.patch_radius * 40.0e9);
        assert!(close(e.deflection, w, 1e-12));
        assert!(close(e.ratio, w / e.overlap, 1e-12));
        assert!(e.patch_radius >= (1e-9 / pi).sqrt());
    }
    // The node regime's ratio is docs/MODEL.md's p_n pi a (1 - nu^2) / (2 E).
    let formula = p_n * pi * node.patch_radius * (1.0 - 0.04) / (2.0 * 40.0e9);
    assert!(close(node.ratio, formula, 1e-12));
}

/// Exact scaling by h (lengths x h, penalty / h, forces x h^2 at a fixed stress, E and
/// nu unchanged) leaves the ratio, hence the decision, unchanged (1e-12); plain coarse
/// graining (the penalty kept) raises it by h in the node regime.
#[test]
fn the_ratio_is_invariant_under_exact_scaling() {
    let pi = std::f64::consts::PI;
    let base = rock(pi * 0.015 * 0.015 / 42.0, 200.0);
    let e0 = deflection_estimate(base, 0.05);
    for h in [0.5, 2.0, 4.0] {
        let exact = DeflectionInputs {
            diameter: base.diameter * h,
            normal_penalty: base.normal_penalty / h,
            node_area: base.node_area * h * h,
            contact_force: base.contact_force * h * h,
            ..base
        };
        let e = deflection_estimate(exact, 0.05);
        assert!(
            close(e.ratio, e0.ratio, 1e-12),
            "h = {h}: {} vs {}",
            e.ratio,
            e0.ratio
        );
        let plain = DeflectionInputs {
            normal_penalty: base.normal_penalty,
            ..exact
        };
        let p = deflection_estimate(plain, 0.05);
        assert!(close(p.ratio, h * e0.ratio, 1e-12), "h = {h}");
    }
}

/// The threshold decides: rigid strictly below, deformable at and above; Love-Weber's
/// mean force gives back its stress, `sigma = phi z f / (pi d^2)`.
#[test]
fn the_threshold_decides_and_the_mean_force_returns_its_stress() {
    let e = deflection_estimate(rock(1.7e-5, 200.0), 0.05);
    assert_eq!(
        deflection_estimate(e.inputs, e.ratio * 1.01).model,
        ParticleModel::Rigid
    );
    assert_eq!(
        deflection_estimate(e.inputs, e.ratio).model,
        ParticleModel::Deformable
    );
    let (sigma, d, phi, z) = (0.8e6, 0.015, 0.62, 4.5);
    let f = mean_contact_force(sigma, d, phi, z);
    assert!(close(
        phi * z * f / (std::f64::consts::PI * d * d),
        sigma,
        1e-12
    ));
}

const SCENE: &str = r#"
[simulation]
duration = 1.0e-5
[material]
density = 2650.0
youngs_modulus = 40.0e9
poisson_ratio = 0.2
[[particle]]
diameter = 0.015
center = [0.0, 0.0, 0.0]
model = "auto"
[[particle]]
diameter = 0.015
center = [0.0152, 0.0, 0.0]
[auto]
contact_force = 200.0
"#;

/// A scene's `auto` particle is resolved from `[auto]`, the material and the penalty:
/// rigid for rock, deformable for a soft material or a threshold below its ratio; the
/// other particle keeps its model. Without `[auto]` the scene is refused at the key
/// `auto` with what to add.
#[test]
fn a_scene_resolves_auto_from_its_material_and_force() {
    let scene = Scene::from_toml_str(SCENE, "auto.toml").unwrap();
    let models = scene.resolved_models().unwrap();
    let estimate = models[0].1.expect("an estimate for the auto particle");
    assert_eq!(models[0].0, ParticleModel::Rigid);
    assert_eq!(models[1], (ParticleModel::Deformable, None));
    let sim = scene.build().unwrap();
    assert_eq!(sim.bodies()[0].kind, fdem_solver::BodyKind::Rigid);
    // The estimate used the template's mean node area at this diameter.
    let template = fdem_solver::MeshSection::default().template().unwrap();
    let area = 0.015 * 0.015 * template.surface.area() / template.surface.nodes.len() as f64;
    assert!(close(estimate.inputs.node_area, area, 1e-12));
    let text = format!("{SCENE}threshold = {}\n", 0.5 * estimate.ratio);
    let strict = Scene::from_toml_str(&text, "auto.toml").unwrap();
    assert_eq!(
        strict.resolved_models().unwrap()[0].0,
        ParticleModel::Deformable
    );
    let soft = SCENE.replace("youngs_modulus = 40.0e9", "youngs_modulus = 1.0e7");
    let soft = Scene::from_toml_str(&soft, "soft.toml").unwrap();
    assert_eq!(
        soft.resolved_models().unwrap()[0].0,
        ParticleModel::Deformable
    );
    assert_eq!(
        soft.build().unwrap().bodies()[0].kind,
        fdem_solver::BodyKind::Deformable
    );
    let without = SCENE.replace("[auto]\ncontact_force = 200.0\n", "");
    let e = Scene::from_toml_str(&without, "auto.toml").unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("auto") && message.contains("contact_force"),
        "{message}"
    );
}
