//! Material validation and derived constants.

use fdem_elastic::{ElasticError, Material};

fn field_of(r: Result<Material, ElasticError>) -> &'static str {
    match r {
        Err(ElasticError::InvalidMaterial { field, .. }) => field,
        other => panic!("expected InvalidMaterial, got {other:?}"),
    }
}

#[test]
fn rejects_each_invalid_field_by_name() {
    for nu in [0.5, 0.6, -1.0, -1.5, f64::NAN, f64::INFINITY] {
        assert_eq!(field_of(Material::new(2650.0, 40e9, nu)), "poisson_ratio");
    }
    for e in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert_eq!(field_of(Material::new(2650.0, e, 0.2)), "youngs_modulus");
    }
    for rho in [0.0, -2650.0, f64::NAN, f64::INFINITY] {
        assert_eq!(field_of(Material::new(rho, 40e9, 0.2)), "density");
    }
    let msg = Material::new(2650.0, 40e9, 0.5).unwrap_err().to_string();
    assert!(
        msg.contains("poisson_ratio") && msg.contains("0.5"),
        "{msg}"
    );
    // Limits are open but values just inside are accepted.
    assert!(Material::new(2650.0, 40e9, 0.4999).is_ok());
    assert!(Material::new(2650.0, 40e9, -0.9999).is_ok());
}

#[test]
fn validate_catches_fields_edited_after_construction() {
    let mut m = Material::new(2650.0, 40e9, 0.2).unwrap();
    m.youngs_modulus = -3.0;
    match m.validate() {
        Err(ElasticError::InvalidMaterial { field, .. }) => assert_eq!(field, "youngs_modulus"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn lame_constants_and_wave_speeds_match_hand_values() {
    // Hand values for E = 40 GPa, nu = 0.2, rho = 2650 (docs/MODEL.md section 3):
    // lambda = 40e9 * 0.2 / (1.2 * 0.6) = 1e11/9, G = 40e9 / 2.4 = 5e10/3,
    // c_p = sqrt((lambda + 2G)/rho) = sqrt(4e11/9/2650) = 4095.3007788930 m/s,
    // c_s = sqrt(G/rho) = sqrt(5e10/3/2650) = 2507.8493128776 m/s.
    // Tolerance 1e-14 relative: a few ulp of the closed forms.
    let m = Material::new(2650.0, 40e9, 0.2).unwrap();
    let rel = |a: f64, b: f64| ((a - b) / b).abs();
    assert!(rel(m.lame_lambda(), 1e11 / 9.0) < 1e-14);
    assert!(rel(m.shear_modulus(), 5e10 / 3.0) < 1e-14);
    assert!(rel(m.p_wave_modulus(), 4e11 / 9.0) < 1e-14);
    assert!(rel(m.p_wave_speed(), 4_095.300_778_893_007_6) < 1e-14);
    assert!(rel(m.s_wave_speed(), 2_507.849_312_877_596) < 1e-14);
}

#[test]
fn material_is_serde() {
    fn is_serde<T: serde::Serialize + for<'de> serde::Deserialize<'de>>() {}
    is_serde::<Material>();
}
