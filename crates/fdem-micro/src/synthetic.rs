//! Synthetic snapshots with a known answer, for tests and benchmarks.
//!
//! Spherical particles of radius `R` sit on a cubic lattice of pitch `2R` (with a small
//! jitter); each lattice neighbour pair touches with a given probability, and particles
//! on the outside touch the six walls. Every contact spreads a force drawn from an
//! exponential distribution over a patch of nodes on a triangular (hexagonal) grid of
//! spacing `s`, the "mesh", in the tangent plane:
//! - **labelled** (fdem's format): each row records its counterpart; a contact shows the
//!   nodes of one particle or of both (each side carrying a share of the force), as
//!   node-to-face contact does;
//! - **label-free** (codes that put action and reaction on both bodies' nodes): both
//!   sides always carry the whole force, equal and opposite, and particle rows record no
//!   counterpart (wall rows keep theirs).
//!
//! The ground truth is computed from the generated contact forces, not from the rows.

use crate::snapshot::{Counterpart, NodeRow, PairRow, Snapshot};
use crate::vec3::{add, cross, norm, scale, sub};

/// Parameters of a synthetic snapshot.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticSpec {
    /// Particles along x, y and z.
    pub grid: [usize; 3],
    /// Particle radius `R` (m).
    pub radius: f64,
    /// Mesh spacing `s` as a fraction of `R`.
    pub spacing_fraction: f64,
    /// Largest patch radius, in mesh spacings (each contact draws its patch radius
    /// uniformly below it; a patch with no grid node inside takes the nearest one).
    pub patch_radius: f64,
    /// Probability that a lattice neighbour pair (or a particle and a wall) touches.
    pub contact_probability: f64,
    /// Labelled mode: probability that a particle contact shows nodes on both sides.
    pub two_sided_probability: f64,
    /// Mean normal contact force (N).
    pub mean_force: f64,
    /// Tangential force up to this fraction of the normal force.
    pub friction: f64,
    /// Labelled (fdem) or label-free rows (see the module docs).
    pub labelled: bool,
    /// Seed of the deterministic random generator.
    pub seed: u64,
}

impl SyntheticSpec {
    /// A specimen of the E2 size: 12 x 12 x 13 = 1,872 particles of radius 5 mm, mesh
    /// spacing R / 4, patches up to 2 spacings (about 4 x 10^4 node rows).
    pub fn e2(seed: u64) -> Self {
        SyntheticSpec {
            grid: [12, 12, 13],
            radius: 5e-3,
            spacing_fraction: 0.25,
            patch_radius: 2.0,
            contact_probability: 0.85,
            two_sided_probability: 0.5,
            mean_force: 1000.0,
            friction: 0.3,
            labelled: true,
            seed,
        }
    }
}

/// A synthetic snapshot and its answer.
#[derive(Clone, Debug, PartialEq)]
pub struct Synthetic {
    /// The node-level snapshot.
    pub snapshot: Snapshot,
    /// Per-pair ground truth in fdem's convention (lower body id, force on it).
    pub truth: Vec<PairRow>,
    /// Number of particle-particle contacts generated.
    pub particle_contacts: usize,
    /// Number of particles.
    pub particles: usize,
    /// The mesh spacing `s` (m).
    pub spacing: f64,
}

/// SplitMix64: a small, well-mixed deterministic generator.
struct Random(u64);

impl Random {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// An orthonormal tangent basis of the unit normal `n`.
fn tangents(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t1 = cross(n, helper);
    let t1 = scale(t1, 1.0 / norm(t1));
    (t1, cross(n, t1))
}

/// Nodes of one side's patch: tangent-plane offsets from the contact point.
fn patch(rng: &mut Random, spacing: f64, radius: f64) -> Vec<[f64; 2]> {
    let angle = rng.uniform() * std::f64::consts::PI / 3.0;
    let a1 = [spacing * angle.cos(), spacing * angle.sin()];
    let b = angle + std::f64::consts::PI / 3.0;
    let a2 = [spacing * b.cos(), spacing * b.sin()];
    let (u, v) = (rng.uniform(), rng.uniform());
    let offset = [u * a1[0] + v * a2[0], u * a1[1] + v * a2[1]];
    let k = (radius / spacing).ceil() as i64 + 2;
    let mut nodes = Vec::new();
    let mut nearest = ([0.0; 2], f64::INFINITY);
    for i in -k..=k {
        for j in -k..=k {
            let p = [
                offset[0] + i as f64 * a1[0] + j as f64 * a2[0],
                offset[1] + i as f64 * a1[1] + j as f64 * a2[1],
            ];
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            if r <= radius {
                nodes.push(p);
            }
            if r < nearest.1 {
                nearest = (p, r);
            }
        }
    }
    if nodes.is_empty() {
        nodes.push(nearest.0);
    }
    nodes
}

struct Generator<'a> {
    spec: &'a SyntheticSpec,
    rng: Random,
    spacing: f64,
    rows: Vec<NodeRow>,
    next_node: Vec<u64>,
}

impl Generator<'_> {
    /// Adds the rows of one side: nodes of `body` at `point + patch + lift n`, carrying
    /// `normal` and `tangential` (the side's totals) spread by weights.
    #[allow(clippy::too_many_arguments)]
    fn side(
        &mut self,
        body: u32,
        counterpart: Counterpart,
        point: [f64; 3],
        n: [f64; 3],
        lift: f64,
        normal: [f64; 3],
        tangential: [f64; 3],
    ) {
        let rho = self.rng.uniform() * self.spec.patch_radius * self.spacing;
        let nodes = patch(&mut self.rng, self.spacing, rho);
        let (t1, t2) = tangents(n);
        let span = rho + self.spacing;
        let weights: Vec<f64> = nodes
            .iter()
            .map(|p| 2.0 - (p[0] * p[0] + p[1] * p[1]) / (span * span))
            .collect();
        let total: f64 = weights.iter().sum();
        for (p, w) in nodes.iter().zip(&weights) {
            let position = add(
                add(point, add(scale(t1, p[0]), scale(t2, p[1]))),
                scale(n, lift * self.spacing),
            );
            let id = &mut self.next_node[body as usize];
            self.rows.push(NodeRow {
                node: u64::from(body) * 1_000_000 + *id,
                body,
                counterpart,
                position,
                depth: 0.01 * self.spacing,
                normal_force: scale(normal, w / total),
                tangential_force: scale(tangential, w / total),
                sliding: false,
            });
            *id += 1;
        }
    }

    /// A random tangential force of up to `friction x force`, perpendicular to `n`.
    fn tangential(&mut self, n: [f64; 3], force: f64) -> [f64; 3] {
        let (t1, t2) = tangents(n);
        let a = self.rng.uniform() * std::f64::consts::TAU;
        let m = self.spec.friction * force * self.rng.uniform();
        add(scale(t1, m * a.cos()), scale(t2, m * a.sin()))
    }

    fn force(&mut self) -> f64 {
        -self.spec.mean_force * (1.0 - self.rng.uniform()).ln()
    }
}

/// Generates a synthetic snapshot (see the module docs).
pub fn generate(spec: &SyntheticSpec) -> Synthetic {
    let [nx, ny, nz] = spec.grid;
    let r = spec.radius;
    let count = nx * ny * nz;
    let mut g = Generator {
        spec,
        rng: Random(spec.seed),
        spacing: spec.spacing_fraction * r,
        rows: Vec::new(),
        next_node: vec![0; count],
    };
    let index = |i: usize, j: usize, k: usize| (i * ny + j) * nz + k;
    let mut centres = vec![[0.0; 3]; count];
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let jitter = [g.rng.uniform(), g.rng.uniform(), g.rng.uniform()]
                    .map(|u| 0.04 * r * (u - 0.5));
                centres[index(i, j, k)] = add(
                    [2.0 * r * i as f64, 2.0 * r * j as f64, 2.0 * r * k as f64],
                    jitter,
                );
            }
        }
    }
    let mut truth = Vec::new();
    let mut particle_contacts = 0;
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let a = index(i, j, k);
                let neighbours = [
                    (i + 1 < nx).then(|| index(i + 1, j, k)),
                    (j + 1 < ny).then(|| index(i, j + 1, k)),
                    (k + 1 < nz).then(|| index(i, j, k + 1)),
                ];
                for b in neighbours.into_iter().flatten() {
                    if g.rng.uniform() >= spec.contact_probability {
                        continue;
                    }
                    particle_contacts += 1;
                    let d = sub(centres[b], centres[a]);
                    let n = scale(d, 1.0 / norm(d)); // from a to b
                    let point = add(centres[a], scale(d, 0.5));
                    let f = g.force();
                    let t = g.tangential(n, f);
                    // Force on a: -n f + t; on b: the opposite.
                    let on_a = (scale(n, -f), t);
                    let (ba, bb) = (a as u32, b as u32);
                    if spec.labelled {
                        let (share, sides) = if g.rng.uniform() < spec.two_sided_probability {
                            (0.3 + 0.4 * g.rng.uniform(), [true, true])
                        } else if g.rng.uniform() < 0.5 {
                            (1.0, [true, false])
                        } else {
                            (0.0, [false, true])
                        };
                        if sides[0] {
                            g.side(
                                ba,
                                Counterpart::Body(bb),
                                point,
                                n,
                                0.01,
                                scale(on_a.0, share),
                                scale(on_a.1, share),
                            );
                        }
                        if sides[1] {
                            g.side(
                                bb,
                                Counterpart::Body(ba),
                                point,
                                n,
                                -0.01,
                                scale(on_a.0, share - 1.0),
                                scale(on_a.1, share - 1.0),
                            );
                        }
                    } else {
                        g.side(ba, Counterpart::Unknown, point, n, 0.01, on_a.0, on_a.1);
                        g.side(
                            bb,
                            Counterpart::Unknown,
                            point,
                            n,
                            -0.01,
                            scale(on_a.0, -1.0),
                            scale(on_a.1, -1.0),
                        );
                    }
                    truth.push(PairRow {
                        body: ba,
                        counterpart: Counterpart::Body(bb),
                        normal_force: on_a.0,
                        tangential_force: on_a.1,
                        nodes: 0,
                    });
                }
                // Walls 0..6: -x, +x, -y, +y, -z, +z.
                let faces = [
                    (i == 0, [-1.0, 0.0, 0.0]),
                    (i + 1 == nx, [1.0, 0.0, 0.0]),
                    (j == 0, [0.0, -1.0, 0.0]),
                    (j + 1 == ny, [0.0, 1.0, 0.0]),
                    (k == 0, [0.0, 0.0, -1.0]),
                    (k + 1 == nz, [0.0, 0.0, 1.0]),
                ];
                for (w, (outside, n)) in faces.into_iter().enumerate() {
                    if !outside || g.rng.uniform() >= spec.contact_probability {
                        continue;
                    }
                    let point = add(centres[a], scale(n, r));
                    let f = g.force();
                    let t = g.tangential(n, f);
                    let wall = Counterpart::Wall(w as u32);
                    g.side(a as u32, wall, point, n, 0.01, scale(n, -f), t);
                    truth.push(PairRow {
                        body: a as u32,
                        counterpart: wall,
                        normal_force: scale(n, -f),
                        tangential_force: t,
                        nodes: 0,
                    });
                }
            }
        }
    }
    truth.sort_by_key(|p| (p.body, p.counterpart));
    Synthetic {
        snapshot: Snapshot {
            time: 0.0,
            rows: g.rows,
        },
        truth,
        particle_contacts,
        particles: count,
        spacing: g.spacing,
    }
}
