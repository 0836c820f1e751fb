//! Construction errors and run-time errors name what, where, and never produce NaN.

use fdem_elastic::{ElasticError, ElementSet};

use crate::common::{kuhn_cube, rock, single_tet};

#[test]
fn unsupported_element_and_bad_lengths() {
    let m = single_tet(false);
    let e = ElementSet::new(&rock(), 8, &m.nodes, &m.conn).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::UnsupportedElement {
            nodes_per_element: 8
        }
    ));
    assert!(e.to_string().contains("use 4"));
    let e = ElementSet::new(&rock(), 4, &m.nodes, &[0, 1, 2, 3, 0]).unwrap_err();
    assert!(matches!(e, ElasticError::ConnectivityLength { len: 5, .. }));
}

#[test]
fn out_of_range_and_repeated_nodes_name_the_element() {
    let m = kuhn_cube(1, 1.0, false);
    let mut conn = m.conn.clone();
    conn[4 * 3 + 2] = 99; // element 3, local node 2
    let e = ElementSet::new(&rock(), 4, &m.nodes, &conn).unwrap_err();
    assert_eq!(
        e,
        ElasticError::NodeOutOfRange {
            element: 3,
            local: 2,
            node: 99,
            n_nodes: 8
        }
    );
    assert!(e.to_string().contains("element 3"), "{e}");
    let mut conn = m.conn.clone();
    conn[4 * 5 + 3] = conn[4 * 5];
    let e = ElementSet::new(&rock(), 4, &m.nodes, &conn).unwrap_err();
    assert!(matches!(e, ElasticError::RepeatedNode { element: 5, .. }));
}

#[test]
fn inverted_and_degenerate_reference_elements_are_rejected() {
    let m = kuhn_cube(1, 1.0, false);
    let mut conn = m.conn.clone();
    conn.swap(4 * 2 + 1, 4 * 2 + 2); // element 2 now clockwise
    let e = ElementSet::new(&rock(), 4, &m.nodes, &conn).unwrap_err();
    assert!(
        matches!(e, ElasticError::InvertedReferenceElement { element: 2, volume } if volume < 0.0)
    );
    assert!(e.to_string().contains("element 2") && e.to_string().contains("swap"));

    let flat = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 1e-12],
    ];
    let e = ElementSet::new(&rock(), 4, &flat, &[0, 1, 2, 3]).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::DegenerateReferenceElement { element: 0, .. }
    ));

    let mut bad = m.nodes.clone();
    bad[6][1] = f64::NAN;
    let e = ElementSet::new(&rock(), 4, &bad, &m.conn).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::NonFiniteRestPosition { node: 6, .. }
    ));
}

#[test]
fn curved_mid_edge_node_is_rejected() {
    let mut m = kuhn_cube(1, 1.0, true);
    let node = m.conn[10 * 4 + 7];
    m.nodes[node][0] += 1e-3;
    let e = ElementSet::new(&rock(), 10, &m.nodes, &m.conn).unwrap_err();
    // The first element using that node is reported; it must be element 4 or earlier.
    match e {
        ElasticError::MidEdgeNodeOffset {
            element,
            node: n,
            offset,
            ..
        } => {
            assert!(element <= 4);
            assert_eq!(n, node);
            assert!((offset - 1e-3).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn slice_lengths_are_checked() {
    let m = kuhn_cube(1, 1.0, false);
    let set = m.element_set();
    let mut f = vec![[0.0; 3]; 8];
    let e = set.add_forces(&m.nodes[..7], &mut f).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::LengthMismatch {
            field: "positions",
            len: 7,
            expected: 8,
            ..
        }
    ));
    let e = set.add_forces(&m.nodes, &mut f[..3]).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::LengthMismatch {
            field: "forces",
            ..
        }
    ));
    let mut out = vec![[0.0; 6]; 2];
    let e = set.cauchy_stresses(&m.nodes, &mut out).unwrap_err();
    assert!(matches!(
        e,
        ElasticError::LengthMismatch {
            field: "out",
            expected: 6,
            ..
        }
    ));
    assert!(set.element_stiffness(6).is_err());
    assert_eq!(set.strain_energy(&m.nodes[..2]), f64::INFINITY);
}

/// Finds an element of `set` that uses `node`, and pushes `node` through the opposite face
/// of the first such element to invert it.
#[test]
fn inverted_current_element_is_an_error_with_its_id_and_no_nan() {
    for quadratic in [false, true] {
        let m = kuhn_cube(2, 1e-2, quadratic);
        let set = m.element_set();
        // Push the centre node (1,1,1)*h far along +x+y+z: several elements invert.
        let centre = 13; // i + 3 (j + 3 k) with i = j = k = 1
        assert_eq!(m.nodes[centre], [1e-2, 1e-2, 1e-2]);
        let mut x = m.nodes.clone();
        for v in &mut x[centre] {
            *v += 1.5e-2;
        }
        let mut f = vec![[0.0; 3]; x.len()];
        let e = set.add_forces(&x, &mut f).unwrap_err();
        let element = match e {
            ElasticError::InvertedElement { element, det_f } => {
                assert!(det_f <= 0.0);
                element
            }
            other => panic!("{other:?}"),
        };
        assert!(set.element_nodes(element).unwrap().contains(&centre));
        assert!(e.to_string().contains(&format!("element {element}")));
        assert!(f.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(set.strain_energy(&x), f64::INFINITY);
        let mut s = vec![[0.0; 6]; set.n_elements()];
        assert!(set.cauchy_stresses(&x, &mut s).is_err());
        assert!(s.iter().flatten().all(|v| v.is_finite()));
    }
}

#[test]
fn quadratic_element_inverted_at_a_corner_only_is_detected() {
    // Moving a mid-edge node 3/4 of the way towards a corner folds the element near that
    // corner (det F < 0 at the corner) while the centroid Jacobian stays positive.
    let m = single_tet(true);
    let set = m.element_set();
    let mut x = m.nodes.clone();
    // node 4 is the midpoint of edge (0,1): move it to 0.1 of the edge from corner 0.
    for k in 0..3 {
        x[4][k] = 0.9 * m.nodes[0][k] + 0.1 * m.nodes[1][k];
    }
    let mut f = vec![[0.0; 3]; 10];
    let e = set.add_forces(&x, &mut f).unwrap_err();
    assert!(
        matches!(e, ElasticError::InvertedElement { element: 0, .. }),
        "{e:?}"
    );
}

#[test]
fn non_finite_positions_are_an_error() {
    for quadratic in [false, true] {
        let m = kuhn_cube(1, 1.0, quadratic);
        let set = m.element_set();
        let mut x = m.nodes.clone();
        x[7][2] = f64::NAN;
        let mut f = vec![[0.0; 3]; x.len()];
        let e = set.add_forces(&x, &mut f).unwrap_err();
        assert!(matches!(e, ElasticError::NonFinitePosition { .. }), "{e:?}");
        x[7][2] = f64::INFINITY;
        let e = set.add_forces(&x, &mut f).unwrap_err();
        assert!(matches!(e, ElasticError::NonFinitePosition { .. }), "{e:?}");
        assert_eq!(set.strain_energy(&x), f64::INFINITY);
    }
}
