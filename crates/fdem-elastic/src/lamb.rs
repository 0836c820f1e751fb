//! Lamb's frequencies of a free homogeneous isotropic elastic sphere (spheroidal modes).
//!
//! Lamb (1882); see also Eringen & Suhubi, *Elastodynamics* vol. II (1975). With `k = omega / c_p`, `h = omega / c_s` and spherical harmonics `Y` of
//! degree `n`, a spheroidal mode is `u = grad(A j_n(k r) Y) + curl curl(r B j_n(h r) Y)`
//! (L1), whose displacement is `u_r = U(r) Y`, `u_t = V(r) grad_S Y` with
//! `U = A k j_n'(kr) + B n(n+1) j_n(hr) / r` and
//! `V = A j_n(kr) / r + B (j_n(hr) / r + h j_n'(hr))` (L2). A free surface at `r = R`
//! has no traction: `sigma_rr = lambda div u + 2 G dU/dr = 0` and
//! `sigma_rt / G = dV/dr - V / r + U / r = 0` (L3). The frequencies are the roots of the
//! 2x2 determinant of (L3) in `(A, B)`; for `n = 0` (breathing, purely radial) `B` drops
//! out and the equation is `(lambda + 2G) j_0(kR) = 4 G j_1(kR) / (kR)` (L4), that is
//! `kR cot kR = 1 - (kR)^2 c_p^2 / (4 c_s^2)`.

use crate::Material;

/// Lowest positive angular frequency (rad/s) of the spheroidal modes of degree `n` of a
/// free sphere of `radius` (m) made of `material`: the first root of (L3) (of (L4) for
/// `n = 0`) in `omega R / c_s` above 0.05, found by a scan in steps of 1e-3 and bisection
/// to round-off. `n = 1` gives its first nonzero root (the zero root is the translation).
pub fn lamb_spheroidal_frequency(material: &Material, radius: f64, n: u32) -> f64 {
    let cs = material.s_wave_speed();
    let ratio = cs / material.p_wave_speed();
    let lambda_over_g = material.lame_lambda() / material.shear_modulus();
    let f = |x: f64| traction_determinant(n, x * ratio, x, lambda_over_g);
    let (mut lo, mut step) = (0.05, 1e-3);
    while f(lo).signum() == f(lo + step).signum() {
        lo += step;
        assert!(
            lo < 100.0,
            "no root of the frequency equation below omega R / c_s = 100"
        );
    }
    let mut hi = lo + step;
    while step > 1e-15 * hi {
        let mid = 0.5 * (lo + hi);
        if f(mid).signum() == f(lo).signum() {
            lo = mid;
        } else {
            hi = mid;
        }
        step = hi - lo;
    }
    0.5 * (lo + hi) * cs / radius
}

/// Determinant of the traction conditions (L3) at `r = 1` for `k = kR`, `h = hR`, over `G`;
/// the radial condition alone (L4) for `n = 0`.
fn traction_determinant(n: u32, k: f64, h: f64, lambda_over_g: f64) -> f64 {
    let nn = f64::from(n * (n + 1));
    let (jk, djk, ddjk) = spherical_bessel(n, k);
    let (jh, djh, ddjh) = spherical_bessel(n, h);
    // sigma_rr / G from A and from B (div u = -k^2 A j_n(kr) Y; dU/dr from (L2)).
    let rr_a = -lambda_over_g * k * k * jk + 2.0 * k * k * ddjk;
    if n == 0 {
        return rr_a;
    }
    let rr_b = 2.0 * nn * (h * djh - jh);
    // sigma_rt / G = V' - V + U at r = 1.
    let rt_a = 2.0 * (k * djk - jk);
    let rt_b = h * h * ddjh + (nn - 2.0) * jh;
    rr_a * rt_b - rr_b * rt_a
}

/// `j_n(x)`, `j_n'(x)` and `j_n''(x)`: `j_0`, `j_1` in closed form, upward recurrence
/// `j_{m+1} = (2m + 1) j_m / x - j_{m-1}`, `j_n' = j_{n-1} - (n + 1) j_n / x`
/// (`j_0' = -j_1`) and the spherical Bessel equation
/// `j_n'' = -2 j_n' / x - (1 - n(n+1) / x^2) j_n`.
fn spherical_bessel(n: u32, x: f64) -> (f64, f64, f64) {
    let (s, c) = x.sin_cos();
    let mut prev = s / x;
    let mut cur = s / (x * x) - c / x;
    if n == 0 {
        let (j, dj) = (prev, -cur);
        return (j, dj, -2.0 * dj / x - j);
    }
    for m in 1..n {
        let next = f64::from(2 * m + 1) * cur / x - prev;
        prev = cur;
        cur = next;
    }
    let nf = f64::from(n);
    let dj = prev - (nf + 1.0) * cur / x;
    let ddj = -2.0 * dj / x - (1.0 - nf * (nf + 1.0) / (x * x)) * cur;
    (cur, dj, ddj)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bessel_functions_match_closed_forms() {
        let x: f64 = 2.3;
        let (s, c) = x.sin_cos();
        let j2 = (3.0 / (x * x) - 1.0) * s / x - 3.0 * c / (x * x);
        assert!((spherical_bessel(2, x).0 - j2).abs() < 1e-15);
        // Derivatives against central differences.
        for n in 0..4 {
            let e = 1e-5;
            let (_, d, dd) = spherical_bessel(n, x);
            let (jp, dp, _) = spherical_bessel(n, x + e);
            let (jm, dm, _) = spherical_bessel(n, x - e);
            assert!((d - (jp - jm) / (2.0 * e)).abs() < 1e-9, "n = {n}");
            assert!((dd - (dp - dm) / (2.0 * e)).abs() < 1e-9, "n = {n}");
        }
    }

    #[test]
    fn breathing_root_matches_love_for_poisson_quarter() {
        // Love, A Treatise on the Mathematical Theory of Elasticity (4th ed., 1927), radial
        // vibrations of a solid sphere: for nu = 1/4, kR / pi = 0.8160, 1.9285, ...
        let m = Material::new(1000.0, 1e9, 0.25).unwrap();
        let omega = lamb_spheroidal_frequency(&m, 1.0, 0);
        let kr_over_pi = omega / m.p_wave_speed() / std::f64::consts::PI;
        assert!((kr_over_pi - 0.8160).abs() < 5e-5, "kR / pi = {kr_over_pi}");
    }

    #[test]
    fn oblate_mode_of_the_paper_grain() {
        // The figure: 140.1 kHz for d = 15 mm, E = 40 GPa, nu = 0.2, rho = 2650.
        let m = Material::new(2650.0, 40e9, 0.2).unwrap();
        let f = lamb_spheroidal_frequency(&m, 0.0075, 2) / (2.0 * std::f64::consts::PI);
        assert!((f / 140.1e3 - 1.0).abs() < 5e-4, "f = {f} Hz");
    }
}
