//! DBSCAN on small 3-D point clouds, and nearest-neighbour spacings.
//!
//! Hand-written (about 60 lines) on top of a brute-force search for small clouds and a
//! kiddo k-d tree for larger ones, rather than petal-clustering: the clouds are the
//! force-carrying nodes of one particle and one counterpart, a few to a few dozen points,
//! thousands of them per snapshot, and on those petal-clustering 0.14 (a ball tree, hash
//! maps and a rayon loop per call) pays its set-up per call and is much slower with
//! identical partitions; it would also bring ndarray into the workspace (docs/MICRO.md,
//! "Why not petal-clustering (measured)", has the timings).

use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Clouds up to this size are searched by brute force (all pairs), larger ones with a
/// k-d tree: the tree's build pays off only on larger clouds, and this limit lies between
/// the sizes where each search was measured faster (`benches/micro.rs`, `dbscan_cloud`;
/// docs/MICRO.md, "Why not petal-clustering (measured)", has the timings).
pub const BRUTE_FORCE_LIMIT: usize = 96;

/// A k-d tree over `points` (items are the indices); `None` if kiddo refuses the points
/// (it reserves the largest float as a sentinel), and the callers then use brute force.
pub(crate) fn tree_of(points: &[[f64; 3]]) -> Option<ImmutableKdTree<f64, 3>> {
    ImmutableKdTree::new_from_slice(points).ok()
}

fn distance2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The eps-neighbourhoods (each point included in its own) in compressed rows:
/// neighbours of `i` are `list[offsets[i]..offsets[i + 1]]`.
struct Neighbourhoods {
    offsets: Vec<usize>,
    list: Vec<usize>,
}

impl Neighbourhoods {
    fn of(&self, i: usize) -> &[usize] {
        &self.list[self.offsets[i]..self.offsets[i + 1]]
    }

    fn build(points: &[[f64; 3]], eps: f64, search: Search) -> Self {
        let n = points.len();
        let eps2 = eps * eps;
        let mut offsets = Vec::with_capacity(n + 1);
        let mut list = Vec::with_capacity(4 * n);
        offsets.push(0);
        let use_tree = match search {
            Search::Auto => n > BRUTE_FORCE_LIMIT,
            Search::BruteForce => false,
            Search::KdTree => true,
        };
        let tree = if use_tree && eps.is_finite() {
            tree_of(points)
        } else {
            None
        };
        match tree {
            Some(tree) => {
                for p in points {
                    let found = tree
                        .query(p)
                        .within::<SquaredEuclidean<f64>>(eps2)
                        .unsorted()
                        .execute();
                    let start = list.len();
                    list.extend(found.iter().map(|r| r.item as usize));
                    // Sorted neighbour lists make the clustering independent of the
                    // tree's traversal order.
                    list[start..].sort_unstable();
                    offsets.push(list.len());
                }
            }
            None => {
                for &p in points {
                    list.extend((0..n).filter(|&j| distance2(p, points[j]) <= eps2));
                    offsets.push(list.len());
                }
            }
        }
        Neighbourhoods { offsets, list }
    }
}

/// DBSCAN (Ester et al. 1996) with the Euclidean distance: a point with at least
/// `min_points` points (itself included) within `eps` (inclusive) is a core point; core
/// points within `eps` of each other share a cluster, and a non-core point within `eps` of
/// a core point joins the first such cluster found (points in index order). Returns the
/// cluster of every point (0, 1, ... in order of each cluster's first point), `None` for
/// noise. With `min_points <= 1` every point is a core point: clusters are the connected
/// components of the eps-graph and isolated points are clusters of their own.
///
/// `eps` may be `f64::INFINITY` (one cluster). Deterministic: the labels depend only on
/// the points and their order.
pub fn dbscan(points: &[[f64; 3]], eps: f64, min_points: usize) -> Vec<Option<u32>> {
    dbscan_with(points, eps, min_points, Search::Auto)
}

/// How [`dbscan_with`] finds neighbourhoods.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Search {
    /// Brute force up to [`BRUTE_FORCE_LIMIT`] points, a k-d tree above.
    #[default]
    Auto,
    /// All pairs.
    BruteForce,
    /// A kiddo k-d tree (brute force when eps is infinite).
    KdTree,
}

/// [`dbscan`] with a chosen neighbourhood search (for benchmarks; the labels do not
/// depend on it).
pub fn dbscan_with(
    points: &[[f64; 3]],
    eps: f64,
    min_points: usize,
    search: Search,
) -> Vec<Option<u32>> {
    let n = points.len();
    let mut labels: Vec<Option<u32>> = vec![None; n];
    if n == 0 {
        return labels;
    }
    let hoods = Neighbourhoods::build(points, eps, search);
    let min_points = min_points.max(1);
    let mut next = 0u32;
    let mut stack = Vec::new();
    for i in 0..n {
        if labels[i].is_some() || hoods.of(i).len() < min_points {
            continue;
        }
        labels[i] = Some(next);
        stack.push(i);
        while let Some(p) = stack.pop() {
            let hood = hoods.of(p);
            if hood.len() < min_points {
                continue; // a border point: it joins, but does not extend the cluster
            }
            for &q in hood {
                if labels[q].is_none() {
                    labels[q] = Some(next);
                    stack.push(q);
                }
            }
        }
        next += 1;
    }
    labels
}

/// Distance from each point to its nearest other point (`None` for a cloud of one point).
/// Coincident points give 0.
pub fn nearest_neighbour_distances(points: &[[f64; 3]]) -> Vec<f64> {
    let n = points.len();
    if n < 2 {
        return Vec::new();
    }
    let brute = |i: usize| {
        (0..n)
            .filter(|&j| j != i)
            .map(|j| distance2(points[i], points[j]))
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    };
    let tree = if n > BRUTE_FORCE_LIMIT {
        tree_of(points)
    } else {
        None
    };
    let Some(tree) = tree else {
        return (0..n).map(brute).collect();
    };
    let two = std::num::NonZero::new(2usize).unwrap_or(std::num::NonZero::<usize>::MIN);
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            tree.query(p)
                .nearest_n::<SquaredEuclidean<f64>>(two)
                .execute()
                .iter()
                .filter(|r| r.item as usize != i)
                .map(|r| r.distance)
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight chain of points with the given gaps, starting at the origin.
    fn chain(gaps: &[f64]) -> Vec<[f64; 3]> {
        let mut x = 0.0;
        let mut out = vec![[0.0; 3]];
        for g in gaps {
            x += g;
            out.push([x, 0.0, 0.0]);
        }
        out
    }

    #[test]
    fn min_points_one_gives_connected_components() {
        let p = chain(&[1.0, 1.0, 3.0, 1.0, 5.0]);
        let l = dbscan(&p, 1.5, 1);
        assert_eq!(
            l,
            vec![Some(0), Some(0), Some(0), Some(1), Some(1), Some(2)]
        );
        // eps is inclusive.
        assert_eq!(dbscan(&p, 3.0, 1)[3], Some(0));
        assert_eq!(dbscan(&p, f64::INFINITY, 1), vec![Some(0); 6]);
    }

    #[test]
    fn min_points_marks_noise_and_border_points() {
        // 0-1-2 dense, 3 a border point of 2 (only 2 neighbours incl. itself), 4 alone.
        let p = chain(&[1.0, 1.0, 1.0, 5.0]);
        let l = dbscan(&p, 1.0, 3);
        assert_eq!(l, vec![Some(0), Some(0), Some(0), Some(0), None]);
        // 3 is not core, so it does not extend the cluster to a point beyond it.
        let p = chain(&[1.0, 1.0, 1.0, 1.0]);
        let l = dbscan(&p, 1.0, 3);
        assert_eq!(l, vec![Some(0); 5]);
    }

    /// Many coincident points (a degenerate input for a k-d tree) are one cluster and
    /// have zero nearest-neighbour distances.
    #[test]
    fn coincident_points() {
        let mut points = vec![[0.5, 0.25, -1.0]; 300];
        points.extend(vec![[2.0, 0.25, -1.0]; 200]);
        let l = dbscan_with(&points, 0.1, 1, Search::KdTree);
        assert!(l[..300].iter().all(|&x| x == Some(0)));
        assert!(l[300..].iter().all(|&x| x == Some(1)));
        assert_eq!(l, dbscan_with(&points, 0.1, 1, Search::BruteForce));
        assert!(
            nearest_neighbour_distances(&points)
                .iter()
                .all(|&d| d == 0.0)
        );
    }

    /// The k-d tree path (more than BRUTE_FORCE_LIMIT points) agrees with brute force.
    #[test]
    fn tree_and_brute_force_agree() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let points: Vec<[f64; 3]> = (0..400).map(|_| [next(), next(), next()]).collect();
        let eps = 0.08;
        let by_tree = dbscan(&points, eps, 1);
        assert_eq!(by_tree, dbscan_with(&points, eps, 1, Search::KdTree));
        let brute = dbscan_with(&points, eps, 1, Search::BruteForce);
        assert_eq!(by_tree, brute);
        // Brute-force reference: union-find over all pairs.
        let mut parent: Vec<usize> = (0..points.len()).collect();
        fn find(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for i in 0..points.len() {
            for j in 0..i {
                if distance2(points[i], points[j]) <= eps * eps {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        for i in 0..points.len() {
            for j in 0..i {
                let same_ref = find(&mut parent, i) == find(&mut parent, j);
                assert_eq!(by_tree[i] == by_tree[j], same_ref, "points {i} and {j}");
            }
        }
        let nn = nearest_neighbour_distances(&points);
        for (i, d) in nn.iter().enumerate() {
            let reference = (0..points.len())
                .filter(|&j| j != i)
                .map(|j| distance2(points[i], points[j]).sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!((d - reference).abs() <= 1e-15, "point {i}");
        }
    }
}
