//! Spheres refined along the radius (`sphere_mesh_in_shells`): the surface is the one-shell
//! mesh's for any number of shells, the elements fill the same polyhedron and conform.

use std::collections::HashMap;

use approx::assert_relative_eq;
use fdem_mesh::geometry::{norm, tet_signed_volume};
use fdem_mesh::{
    ElementOrder, MAX_SHELLS, MeshError, Sizing, SphereSpec, TET_EDGES, TetMesh, sphere_mesh,
    sphere_mesh_in_shells,
};

const D: f64 = 0.015;
const ORDERS: [ElementOrder; 2] = [ElementOrder::Linear, ElementOrder::Quadratic];

fn spec(level: u32, order: ElementOrder, sizing: Sizing) -> SphereSpec {
    SphereSpec {
        level,
        order,
        diameter: D,
        sizing,
    }
}

fn shelled(level: u32, order: ElementOrder, shells: u32) -> TetMesh {
    sphere_mesh_in_shells(&spec(level, order, Sizing::Inscribed), shells).expect("valid spec")
}

#[test]
fn one_shell_is_the_sphere_mesh() {
    for level in 0..=4 {
        for order in ORDERS {
            for sizing in [Sizing::Inscribed, Sizing::VolumeEquivalent] {
                let s = spec(level, order, sizing);
                assert_eq!(
                    sphere_mesh_in_shells(&s, 1).unwrap(),
                    sphere_mesh(&s).unwrap()
                );
            }
        }
    }
}

#[test]
fn surface_nodes_and_volume_do_not_depend_on_shells() {
    for level in 0..=3 {
        for order in ORDERS {
            for sizing in [Sizing::Inscribed, Sizing::VolumeEquivalent] {
                let one = sphere_mesh(&spec(level, order, sizing)).unwrap();
                let n_surface = one.surface.nodes.len();
                for shells in 2..=4 {
                    let m = sphere_mesh_in_shells(&spec(level, order, sizing), shells).unwrap();
                    m.validate().unwrap();
                    assert_eq!(m.surface, one.surface, "level {level} {order:?} {shells}");
                    assert_eq!(m.nodes[..n_surface], one.nodes[..n_surface]);
                    assert_relative_eq!(m.volume(), one.volume(), max_relative = 1e-13);
                }
            }
        }
    }
}

#[test]
fn counts_follow_the_layer_formulas() {
    // F faces, V surface vertices, E = 3F/2 surface edges; k shells: F (3k - 2) tets,
    // k V + 1 corners; edges: k E on the shells, k V radial, (k - 1) E prism diagonals.
    for level in 0..=3u32 {
        let f = 20 * 4usize.pow(level);
        let v = f / 2 + 2;
        let e = 3 * f / 2;
        for k in 1..=MAX_SHELLS as usize {
            let lin = shelled(level, ElementOrder::Linear, k as u32);
            assert_eq!(lin.n_elements(), f * (3 * k - 2));
            assert_eq!(lin.n_nodes(), k * v + 1);
            let quad = shelled(level, ElementOrder::Quadratic, k as u32);
            assert_eq!(quad.n_elements(), f * (3 * k - 2));
            assert_eq!(quad.n_nodes(), k * v + 1 + k * e + k * v + (k - 1) * e);
        }
    }
}

#[test]
fn elements_are_positive_and_conform() {
    for level in 0..=2 {
        for shells in 1..=4 {
            let m = shelled(level, ElementOrder::Linear, shells);
            // Every element face is shared by two elements with opposite orientation,
            // except the surface faces, which are the surface triangles.
            let mut faces: HashMap<[usize; 3], i32> = HashMap::new();
            for e in 0..m.n_elements() {
                let x = m.corners(e);
                assert!(tet_signed_volume(x[0], x[1], x[2], x[3]) > 0.0);
                let t = m.element(e);
                for [a, b, c] in [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]] {
                    let mut key = [t[a], t[b], t[c]];
                    key.sort_unstable();
                    *faces.entry(key).or_default() += 1;
                }
            }
            let mut boundary: Vec<[usize; 3]> = faces
                .into_iter()
                .filter(|&(_, n)| {
                    assert!(n == 1 || n == 2, "a face with {n} elements");
                    n == 1
                })
                .map(|(k, _)| k)
                .collect();
            boundary.sort_unstable();
            let mut surface: Vec<[usize; 3]> = m
                .surface
                .triangles
                .iter()
                .map(|t| {
                    let mut k = *t;
                    k.sort_unstable();
                    k
                })
                .collect();
            surface.sort_unstable();
            assert_eq!(boundary, surface, "level {level}, {shells} shells");
        }
    }
}

#[test]
fn shells_are_equally_spaced_and_mid_edge_nodes_are_midpoints() {
    let (level, shells) = (2, 3);
    let m = shelled(level, ElementOrder::Quadratic, shells);
    let r = 0.5 * D;
    let mut radii: Vec<f64> = Vec::new();
    for e in 0..m.n_elements() {
        let el = m.element(e);
        for (k, &(i, j)) in TET_EDGES.iter().enumerate() {
            let (a, b, mid) = (m.nodes[el[i]], m.nodes[el[j]], m.nodes[el[4 + k]]);
            for c in 0..3 {
                assert_relative_eq!(mid[c], 0.5 * (a[c] + b[c]), epsilon = 1e-18);
            }
        }
        for &n in &el[..4] {
            radii.push(norm(m.nodes[n]) / r);
        }
    }
    for x in radii {
        let s = x * shells as f64;
        assert!((s - s.round()).abs() < 1e-12, "corner at radius {x} R");
    }
}

#[test]
fn shell_count_errors() {
    let s = spec(1, ElementOrder::Linear, Sizing::Inscribed);
    for shells in [0, MAX_SHELLS + 1] {
        let err = sphere_mesh_in_shells(&s, shells).unwrap_err();
        assert!(matches!(err, MeshError::ShellsOutOfRange { .. }));
        assert!(
            err.to_string().contains(&format!("1..={MAX_SHELLS}")),
            "{err}"
        );
    }
    assert!(sphere_mesh_in_shells(&s, MAX_SHELLS).is_ok());
}
