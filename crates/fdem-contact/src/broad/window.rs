//! The contact window of a face, and how near to it a node behind the face's plane must be
//! for the pair to be listed.
//!
//! The narrow phase accepts a node behind a face only when the foot of its perpendicular
//! falls inside the face (barycentric coordinates `>= -tau`, [`BARYCENTRIC_TOLERANCE`]) and
//! it lies at most the depth limit `D` behind the plane: the node is then in the face's
//! *window*, the prism over the face (in its tolerance band) from `D` behind the plane to
//! its front. (The closest-face rule looks at faces that cover a node from the front by
//! less than a hit's depth, at most `D / 2`; the window therefore reaches `D` in front as
//! well, which costs nothing below since a node behind the plane is nearest to the
//! window's back part.) The distance to the face alone lists every node within
//! `skin + D` of the face in any direction, most of them beside the window, where no
//! motion within the lists' allowances can bring them in.
//!
//! **The bound.** Let the lists hold while the node moves at most `a_x` and each corner of
//! the face at most `a_f` from where they were when the pair was found. Suppose the node is
//! in the window later: `x' = p' + z' n'` with `p' = sum w_i c'_i` (weights in the band),
//! `|z'| <= D`. The point `q = sum w_i c_i + z' n` lies in the window as found, and
//!
//! `|x - q| <= |x - x'| + |p' - p| + |z'| |n' - n| <= a_x + a_f (1 + 4 tau) + D |n' - n|`.
//!
//! With `u`, `v` the face's two shorter edges from their common corner and `N = u x v`,
//! the corners' motions change each edge by at most `2 a_f`, so `|N' - N| <= delta =
//! 2 a_f (|u| + |v|) + 4 a_f^2`; the map `y -> y / |y|` is `1/r`-Lipschitz outside the ball
//! of radius `r`, so `|n' - n| <= delta / (|N| - delta)` while `delta < |N|` (and at most
//! 2 always). A node behind the plane at depth `z` whose foot lies `l` from the face (in
//! the plane) is at distance `sqrt(l^2 + max(z - D, 0)^2)` from the window, so a pair whose
//! distance exceeds that reach can never hit (the band adds `4 tau` times the longest
//! edge, the distance between the face and its band).
//!
//! **Under a mean motion** (`crate::mean_motion`) the drift is measured from where the mean
//! map `M` (within `g` of the identity between any two evaluations of an epoch) takes the
//! references. Pulled back by that map the same argument holds, with two additions: the
//! map changes an edge `u` by at most `g |u|` (so each edge changes by `2 a_f + g |u|`), and
//! the pull-back of `z' n'` differs from `z'` times the pulled-back face's normal by at
//! most `3 g / (1 - g) D` (the map's own stretch of `z' n'` and the tilt of the normal,
//! which turns with the inverse transpose). The lists' drift allowance renews the lists
//! before `g L` exceeds [`crate::mean_motion::DISTORTION_FRACTION`] of half the skin,
//! `L` the lists' reach length (at least `skin + D`), which bounds `g` here.
//!
//! Sheets keep the distance test alone (their edge contacts need the faces beside a node),
//! and so do nodes in front of the plane (the front reach, `FRONT_SKINS`).

use crate::mean_motion::DISTORTION_FRACTION;
use crate::narrow::BARYCENTRIC_TOLERANCE;
use crate::vec3::{cross, norm, sub};

/// The motions a set of lists allows between the time its pairs are found and their
/// renewal, and the depth of the window: what [`WindowReach::of_face`] needs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct WindowReach {
    /// How far a node may move (m).
    pub(crate) node: f64,
    /// How far each corner of a face may move (m).
    pub(crate) corner: f64,
    /// The depth limit `D` (m).
    pub(crate) depth: f64,
    /// The largest distortion `g` of the mean map within an epoch.
    pub(crate) distortion: f64,
}

impl WindowReach {
    /// The allowances of the lists of a full build with Verlet skin `skin`: every node
    /// and corner moves at most half a skin.
    pub(crate) fn of_build(skin: f64, depth: f64) -> WindowReach {
        WindowReach {
            node: 0.5 * skin,
            corner: 0.5 * skin,
            depth,
            distortion: largest_distortion(skin, depth),
        }
    }

    /// The allowances of a refresh's pairs: one end moves at most half a skin from its new
    /// reference, the other up to a whole skin from where it is (it may have drifted half
    /// a skin already and may drift as far again the other way); either may be the face.
    pub(crate) fn of_refresh(skin: f64, depth: f64) -> WindowReach {
        WindowReach {
            node: skin,
            corner: skin,
            depth,
            distortion: largest_distortion(skin, depth),
        }
    }

    /// The window of `face` for the candidate test ([`FaceWindow`]): its reach is computed
    /// only for a node beyond the least reach, and then kept.
    pub(crate) fn of_face_lazily(self, face: [[f64; 3]; 3]) -> FaceWindow {
        FaceWindow {
            allow: self,
            face,
            reach: None,
        }
    }

    /// The first two terms of [`WindowReach::of_face`]'s sum, those of every face: the node's
    /// and the corners' motions. The other terms are not negative and are added after
    /// these, so no face's reach is below this one in floating point either.
    fn least(&self) -> f64 {
        self.node + self.corner * (1.0 + 4.0 * BARYCENTRIC_TOLERANCE)
    }

    /// How far from the window of `face` (m) a node behind its plane may be and still be
    /// in it before the lists are renewed (module documentation).
    pub(crate) fn of_face(&self, face: [[f64; 3]; 3]) -> f64 {
        let [a, b, c] = face;
        let mut edges = [norm(sub(b, a)), norm(sub(c, b)), norm(sub(a, c))];
        edges.sort_by(f64::total_cmp);
        let [short, middle, longest] = edges;
        let area2 = norm(cross(sub(b, a), sub(c, a)));
        let g = self.distortion;
        let (du, dv) = (
            2.0 * self.corner + g * short,
            2.0 * self.corner + g * middle,
        );
        let delta = du * middle + short * dv + du * dv;
        let turn = if delta < area2 {
            (delta / (area2 - delta)).min(2.0)
        } else {
            2.0
        };
        let band = 4.0 * BARYCENTRIC_TOLERANCE * longest;
        let mean_tilt = 3.0 * g / (1.0 - g) * self.depth;
        self.least() + self.depth * turn + mean_tilt + band
    }
}

/// The largest distortion of the mean map the lists allow before a full build (see
/// `crate::mean_motion::DriftAllowance`): `g L <= DISTORTION_FRACTION * skin / 2` with the
/// reach length `L >= skin + D`.
fn largest_distortion(skin: f64, depth: f64) -> f64 {
    DISTORTION_FRACTION * 0.5 * skin / (skin + depth)
}

/// The squared distance from the window of depth `window_depth` of a node behind the face's
/// plane by `depth` and at squared distance `d2` from the face.
#[inline(always)]
fn from_window2(d2: f64, depth: f64, window_depth: f64) -> f64 {
    // The foot's squared distance from the face in its plane: d2 = l^2 + z^2 for a node
    // whose nearest point of the face is the nearest point to its foot.
    let lateral2 = (d2 - depth * depth).max(0.0);
    let beyond = (depth - window_depth).max(0.0);
    lateral2 + beyond * beyond
}

/// Whether a squared distance `far2` from a window is within `reach` of it. Monotone in
/// `reach`: a larger reach never turns a pass into a failure, rounding included.
#[inline(always)]
fn within(far2: f64, reach: f64) -> bool {
    far2 <= reach * reach * (1.0 + WINDOW_SLACK)
}

/// The window of one face as the candidate test asks for it: whether a node behind the
/// face's plane lies within the face's reach ([`WindowReach::of_face`]) of its window. A
/// node within the least reach of every face ([`WindowReach::least`]) passes without the
/// face's own reach; for one farther out the reach is computed and kept for the face's next
/// node. The answer is the one with the face's reach, bit for bit: the least reach is a
/// partial sum of that reach, and [`within`] is monotone.
pub(crate) struct FaceWindow {
    allow: WindowReach,
    face: [[f64; 3]; 3],
    reach: Option<f64>,
}

impl FaceWindow {
    /// Whether a node behind the face's plane by `depth` and at squared distance `d2` from
    /// the face lies within the face's window reach.
    #[inline(always)]
    pub(crate) fn holds(&mut self, d2: f64, depth: f64) -> bool {
        let far2 = from_window2(d2, depth, self.allow.depth);
        if within(far2, self.allow.least()) {
            return true;
        }
        let (allow, face) = (self.allow, self.face);
        within(far2, *self.reach.get_or_insert_with(|| allow.of_face(face)))
    }
}

/// Relative slack of the window test, far above the round-off of `d2 - z^2`.
const WINDOW_SLACK: f64 = 1e-6;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::narrow::{ProjectionKernel, distance2_to_triangle};
    use crate::vec3::{add, dot, scale};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg64;

    fn moved(p: [f64; 3], r: &mut Pcg64, by: f64) -> [f64; 3] {
        // A random displacement of length at most `by`.
        loop {
            let d = [0; 3].map(|_| r.random_range(-1.0..1.0));
            if dot(d, d) <= 1.0 {
                return add(p, scale(d, by));
            }
        }
    }

    /// Whether a node behind the plane of a face by `depth` and at squared distance `d2` from
    /// the face lies within `reach` of the face's window of depth `window_depth`: the test
    /// with a face's own reach, which [`FaceWindow::holds`] answers.
    fn near_window(d2: f64, depth: f64, window_depth: f64, reach: f64) -> bool {
        within(from_window2(d2, depth, window_depth), reach)
    }

    /// A random face of about 4 mm in the plane `z = 0` (outward normal `+z`), and the
    /// allowances of a build or of a refresh at random.
    fn random_face(r: &mut Pcg64, (skin, depth): (f64, f64)) -> ([[f64; 3]; 3], WindowReach) {
        let face = [
            [0.0, 0.0, 0.0],
            [4e-3 + r.random_range(-1e-3..1e-3), 0.0, 0.0],
            [r.random_range(0.0..4e-3), r.random_range(2e-3..4e-3), 0.0],
        ];
        let allow = if r.random_range(0.0..1.0) < 0.5 {
            WindowReach::of_build(skin, depth)
        } else {
            WindowReach::of_refresh(skin, depth)
        };
        (face, allow)
    }

    /// Random faces, nodes and motions within the allowances: every node that ends in
    /// the moved face's window (the hand kernel accepts it) started within the window
    /// reach of the face as found, or in front of its plane.
    #[test]
    fn every_node_that_reaches_the_window_was_within_its_reach() {
        let mut r = Pcg64::seed_from_u64(7);
        let (skin, depth) = (0.25e-3, 1.75e-3);
        let mut hits = 0;
        let mut tight = 0.0_f64;
        for _ in 0..400_000 {
            let (face, allow) = random_face(&mut r, (skin, depth));
            let x = [
                r.random_range(-3e-3..7e-3),
                r.random_range(-3e-3..7e-3),
                r.random_range(-2.5e-3..0.5e-3),
            ];
            // The worst motions lie at the allowances' full length: push the corners
            // apart or together at random, the node anywhere within its reach.
            let moved_face = face.map(|c| moved(c, &mut r, allow.corner));
            let x_moved = moved(x, &mut r, allow.node);
            let Some(_) = ProjectionKernel::Hand.project(x_moved, moved_face, depth) else {
                continue;
            };
            hits += 1;
            let n = cross(sub(face[1], face[0]), sub(face[2], face[0]));
            let s = dot(n, sub(x, face[0])) / norm(n);
            if s >= 0.0 {
                continue;
            }
            let d2 = distance2_to_triangle(x, face);
            let reach = allow.of_face(face);
            assert!(near_window(d2, -s, depth, reach), "{x:?} {face:?}");
            let lateral = (d2 - s * s).max(0.0).sqrt();
            tight = tight.max(lateral / reach);
        }
        assert!(hits > 10_000, "{hits}");
        // The bound is not vacuous: some nodes came from well beside the face.
        assert!(tight > 0.3, "{tight}");
    }

    /// The worst motion for a deep window: the corners of one edge move out and up, the
    /// far corner out and down (each by the whole allowance), turning the face so that its
    /// window, the depth limit deep, sweeps beside that edge; the node moves in. A node
    /// found farther beside the edge than the motions alone (node, corners and the mean
    /// map's tilt) reaches the window, so the reach needs the turn of the normal.
    #[test]
    fn the_turn_of_the_face_brings_a_deep_node_beside_it_into_the_window() {
        let (l, depth, skin) = (4e-3, 4e-3, 0.25e-3);
        let allow = WindowReach::of_build(skin, depth);
        let a = allow.corner;
        let face = [[0.0, 0.0, 0.0], [l, 0.0, 0.0], [0.0, l, 0.0]];
        let (cos, sin) = (1.0 / 5.0_f64.sqrt(), 2.0 / 5.0_f64.sqrt());
        let up = [-a * cos, 0.0, a * sin];
        let down = [-a * cos, 0.0, -a * sin];
        let moved = [add(face[0], up), add(face[1], down), add(face[2], up)];
        let beside = |x: f64| [-x, 0.25 * l, -0.97 * depth];
        // The farthest node beside the edge that the moved window accepts.
        let farthest = (0..2000)
            .map(|i| i as f64 * 0.5e-6)
            .filter(|&x| {
                let x_moved = add(beside(x), [allow.node, 0.0, 0.0]);
                ProjectionKernel::Hand
                    .project(x_moved, moved, depth)
                    .is_some()
            })
            .fold(0.0_f64, f64::max);
        let without_turn = allow.node
            + allow.corner * (1.0 + 4.0 * BARYCENTRIC_TOLERANCE)
            + 3.0 * allow.distortion / (1.0 - allow.distortion) * depth;
        assert!(farthest > 1.2 * without_turn, "{farthest} {without_turn}");
        let x = beside(farthest);
        let d2 = distance2_to_triangle(x, face);
        assert!(near_window(d2, -x[2], depth, allow.of_face(face)));
    }

    #[test]
    fn the_reach_is_far_below_the_distance_test_on_a_particle_face() {
        // An equilateral face of 4.1 mm, the E1 particles' size, at the test's skin and a
        // grown depth limit: the window reach is a fraction of skin + depth.
        let l = 4.1e-3;
        let face = [[0.0, 0.0, 0.0], [l, 0.0, 0.0], [0.5 * l, 0.866 * l, 0.0]];
        let (skin, depth) = (0.256e-3, 1.73e-3);
        let build = WindowReach::of_build(skin, depth).of_face(face);
        let refresh = WindowReach::of_refresh(skin, depth).of_face(face);
        assert!(build < 0.5 * (skin + depth), "{build}");
        assert!(refresh > build && refresh < skin + depth, "{refresh}");
        // A degenerate face keeps the widest reach (the normal may turn by anything).
        let flat = [[0.0; 3], [l, 0.0, 0.0], [2.0 * l, 0.0, 0.0]];
        let wide = WindowReach::of_build(skin, depth).of_face(flat);
        assert!(wide >= 2.0 * depth, "{wide}");
    }

    /// The face's window answers as the test with its own reach, node by node, for nodes
    /// on both sides of the least reach and of the face's reach, and computes the face's
    /// reach only for a node beyond the least one.
    #[test]
    fn the_face_window_is_the_test_with_the_face_reach_bit_for_bit() {
        let mut r = Pcg64::seed_from_u64(11);
        let (skin, depth) = (0.25e-3, 1.75e-3);
        let (mut lazy, mut computed) = (0, 0);
        for _ in 0..20_000 {
            let (face, allow) = random_face(&mut r, (skin, depth));
            let reach = allow.of_face(face);
            let mut window = allow.of_face_lazily(face);
            for _ in 0..4 {
                // A node whose distance from the window spans both reaches.
                let far = r.random_range(0.0..1.5) * reach;
                let z = r.random_range(0.0..depth + far);
                let beyond = (z - depth).max(0.0);
                let lateral2 = (far * far - beyond * beyond).max(0.0);
                let d2 = lateral2 + z * z;
                let before = window.reach.is_some();
                assert_eq!(
                    window.holds(d2, z),
                    near_window(d2, z, depth, reach),
                    "{face:?} {d2} {z}"
                );
                let least = allow.least();
                if within(from_window2(d2, z, depth), least) {
                    lazy += 1;
                    assert_eq!(window.reach.is_some(), before);
                } else {
                    computed += 1;
                    assert_eq!(window.reach, Some(reach));
                }
            }
        }
        assert!(lazy > 10_000 && computed > 10_000, "{lazy} {computed}");
    }

    #[test]
    fn a_node_beside_the_face_is_out_of_the_window_and_one_below_it_is_in() {
        let face = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // Behind by 0.5 (outward normal +z), foot 0.3 beside the edge x = 0.
        let x = [-0.3, 0.5, -0.5];
        let d2 = distance2_to_triangle(x, face);
        assert!(near_window(d2, 0.5, 1.0, 0.31));
        assert!(!near_window(d2, 0.5, 1.0, 0.29));
        // Deeper than the window by 0.4, foot inside.
        let y = [0.2, 0.2, -1.4];
        let d2 = distance2_to_triangle(y, face);
        assert!(near_window(d2, 1.4, 1.0, 0.41) && !near_window(d2, 1.4, 1.0, 0.39));
    }
}
