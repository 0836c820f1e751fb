//! Random loose placement: non-overlapping spheres in a vertical cylinder, with uniformly
//! random orientations. Centres start uniformly at random (overlaps allowed) and overlapping
//! pairs are pushed apart until none is left (relaxation sweeps over the pairs a uniform
//! grid finds among the 27 cells around each sphere, never all pairs). Unlike random
//! sequential addition, which jams near a sphere fraction of 0.38 in bulk and far lower in
//! a narrow cylinder, this reaches the loose fractions a preparation asks for, up to about
//! the largest accepted (docs/SPECIMENS.md, "Preparation: the dynamic method", has the
//! fractions reached).

use fdem_core::space_order::morton_order;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

/// Relaxation sweeps before the column is declared too full.
pub const MAX_SWEEPS: usize = 5_000;
/// Each push separates an overlapping pair by this factor times the overlap (slight
/// over-relaxation, so that pairs do not end exactly in contact and sweeps converge).
const PUSH_FACTOR: f64 = 1.05;
/// Relative shortfall of a pair's distance below its reach that counts as separated
/// (round-off).
const SEPARATED: f64 = 1e-13;
/// Each push separates a pair by this much of its reach beyond the overlap, so that pairs
/// pressed together by the projections onto the walls do not stall at round-off.
const PUSH_EXTRA: f64 = 1e-9;

/// One placed particle: the reference placement of its template mesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlacedParticle {
    /// Simulated nominal diameter (m).
    pub diameter: f64,
    /// Centre (m).
    pub center: [f64; 3],
    /// Orientation, unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Size class (index into the gradation).
    pub class: usize,
}

/// A vertical cylinder `x^2 + y^2 <= radius^2`, `bottom <= z <= top`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Column {
    /// Inner radius (m).
    pub radius: f64,
    /// Lower end (m).
    pub bottom: f64,
    /// Upper end (m).
    pub top: f64,
}

/// Why a placement failed: the particle (in placement order) of the largest overlap found
/// by the last sweep, or one that does not fit the column at all.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoRoom {
    /// Index in placement order.
    pub particle: usize,
    /// Its diameter (m).
    pub diameter: f64,
}

/// A uniformly random rotation as a unit quaternion `[w, x, y, z]` (Shoemake's method).
pub fn random_rotation(rng: &mut Pcg64) -> [f64; 4] {
    let u1: f64 = rng.random_range(0.0..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    let u3: f64 = rng.random_range(0.0..1.0);
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = [
        b * (tau * u3).cos(),
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
    ];
    // Normalise away the round-off so the norm is 1 to the last bits.
    let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    q.map(|c| c / n)
}

/// Uniform grid over the column holding the indices of placed particles.
struct Grid {
    cell: f64,
    origin: [f64; 3],
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Grid {
    fn new(column: &Column, cell: f64) -> Grid {
        let origin = [-column.radius, -column.radius, column.bottom];
        let extent = [
            2.0 * column.radius,
            2.0 * column.radius,
            column.top - column.bottom,
        ];
        let dims = extent.map(|e| ((e / cell).ceil() as usize).max(1));
        Grid {
            cell,
            origin,
            dims,
            cells: vec![Vec::new(); dims[0] * dims[1] * dims[2]],
        }
    }

    fn coords(&self, x: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|k| {
            let i = ((x[k] - self.origin[k]) / self.cell).floor();
            (i.max(0.0) as usize).min(self.dims[k] - 1)
        })
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    fn insert(&mut self, x: [f64; 3], id: u32) {
        let i = self.index(self.coords(x));
        self.cells[i].push(id);
    }

    /// Calls `f` with every particle id in the 27 cells around `x`; stops at `false`.
    fn all_near(&self, x: [f64; 3], mut f: impl FnMut(u32) -> bool) -> bool {
        let c = self.coords(x);
        let range = |k: usize| c[k].saturating_sub(1)..=(c[k] + 1).min(self.dims[k] - 1);
        for k in range(2) {
            for j in range(1) {
                for i in range(0) {
                    for &id in &self.cells[self.index([i, j, k])] {
                        if !f(id) {
                            return false;
                        }
                    }
                }
            }
        }
        true
    }
}

/// Places spheres of the given diameters (with their size class) at random in `column`,
/// without overlap: two spheres are at least `clearance` apart, and every sphere stays
/// `clearance` inside the cylinder and its ends. The result is numbered largest diameters
/// first, and spheres of one diameter along a space-filling curve ([`number_in_space`]).
///
/// Centres start uniformly at random in the region each sphere may occupy; then sweeps
/// over all overlapping pairs (found through a grid of cell d_max + clearance) push each
/// pair apart along the line of centres, each sphere by half of `PUSH_FACTOR` times the
/// overlap, and project the spheres back into their regions, until a sweep finds no overlap
/// (at most [`MAX_SWEEPS`] sweeps). Deterministic for a given `seed`.
pub fn place_spheres(
    diameters: &[(f64, usize)],
    column: &Column,
    clearance: f64,
    seed: u64,
) -> Result<Vec<PlacedParticle>, NoRoom> {
    let mut order: Vec<usize> = (0..diameters.len()).collect();
    order.sort_by(|&a, &b| diameters[b].0.total_cmp(&diameters[a].0).then(a.cmp(&b)));
    let d_max = diameters.iter().map(|d| d.0).fold(0.0, f64::max);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut placed: Vec<PlacedParticle> = Vec::with_capacity(diameters.len());
    let mut regions: Vec<Region> = Vec::with_capacity(diameters.len());
    for (n, &i) in order.iter().enumerate() {
        let (d, class) = diameters[i];
        let region = Region::of(column, 0.5 * d, clearance).ok_or(NoRoom {
            particle: n,
            diameter: d,
        })?;
        // Uniform in the disc of radius `radial` and in [z0, z1].
        let rho = region.radial * rng.random_range(0.0f64..1.0).sqrt();
        let theta = std::f64::consts::TAU * rng.random_range(0.0f64..1.0);
        let z = if region.z1 > region.z0 {
            rng.random_range(region.z0..region.z1)
        } else {
            region.z0
        };
        placed.push(PlacedParticle {
            diameter: d,
            center: [rho * theta.cos(), rho * theta.sin(), z],
            orientation: random_rotation(&mut rng),
            class,
        });
        regions.push(region);
    }
    let mut near: Vec<u32> = Vec::new();
    let mut last_worst = 0;
    for _ in 0..MAX_SWEEPS {
        let mut grid = Grid::new(column, d_max + clearance);
        for (id, p) in placed.iter().enumerate() {
            grid.insert(p.center, id as u32);
        }
        let mut worst: Option<(f64, usize)> = None;
        for i in 0..placed.len() {
            near.clear();
            grid.all_near(placed[i].center, |id| {
                if id as usize > i {
                    near.push(id);
                }
                true
            });
            for &j in &near {
                let j = j as usize;
                let (a, b) = (&placed[i], &placed[j]);
                let reach = 0.5 * (a.diameter + b.diameter) + clearance;
                let mut dx: [f64; 3] = std::array::from_fn(|k| b.center[k] - a.center[k]);
                let dist = dx.iter().map(|v| v * v).sum::<f64>().sqrt();
                // Shortfalls of round-off size (a pair held together by the projections)
                // count as separated.
                if dist >= reach * (1.0 - SEPARATED) {
                    continue;
                }
                if worst.is_none_or(|w| reach - dist > w.0) {
                    worst = Some((reach - dist, i));
                }
                if dist > 0.0 {
                    dx = dx.map(|v| v / dist);
                } else {
                    // Coincident centres: separate along a random direction.
                    let q = random_rotation(&mut rng);
                    dx = [q[1], q[2], q[3]];
                    let l = dx.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
                    dx = dx.map(|v| v / l);
                }
                let push = 0.5 * (PUSH_FACTOR * (reach - dist) + PUSH_EXTRA * reach);
                for (k, u) in dx.iter().enumerate() {
                    placed[i].center[k] -= push * u;
                    placed[j].center[k] += push * u;
                }
                regions[i].project(&mut placed[i].center);
                regions[j].project(&mut placed[j].center);
            }
        }
        match worst {
            None => return Ok(number_in_space(placed)),
            Some((_, i)) => last_worst = i,
        }
    }
    // Still overlapping: the particle of the largest overlap the last sweep found.
    Err(NoRoom {
        particle: last_worst,
        diameter: placed[last_worst].diameter,
    })
}

/// Numbers each run of equal diameters along the Morton curve of their centres: particles
/// near each other in space come near each other in the body order, and so do their nodes
/// and faces in every array the engine keeps. The contact passes read the faces and nodes
/// of each node's neighbours; numbered at random (placement order) those lie anywhere in
/// memory (docs/PERFORMANCE.md, "Numbering the particles along a space-filling curve").
fn number_in_space(placed: Vec<PlacedParticle>) -> Vec<PlacedParticle> {
    let mut numbered = Vec::with_capacity(placed.len());
    for group in placed.chunk_by(|a, b| a.diameter == b.diameter) {
        let centres: Vec<[f64; 3]> = group.iter().map(|p| p.center).collect();
        numbered.extend(morton_order(&centres).into_iter().map(|i| group[i].clone()));
    }
    numbered
}

/// Where the centre of a sphere may lie: within `radial` of the axis, between `z0` and `z1`.
#[derive(Clone, Copy, Debug)]
struct Region {
    radial: f64,
    z0: f64,
    z1: f64,
}

impl Region {
    /// The region of a sphere of radius `r` kept `clearance` inside `column`; `None` when
    /// the sphere does not fit.
    fn of(column: &Column, r: f64, clearance: f64) -> Option<Region> {
        let radial = column.radius - r - clearance;
        let (z0, z1) = (column.bottom + r + clearance, column.top - r - clearance);
        (radial >= 0.0 && z1 >= z0).then_some(Region { radial, z0, z1 })
    }

    /// Moves `x` to the nearest point of the region.
    fn project(&self, x: &mut [f64; 3]) {
        let rho = x[0].hypot(x[1]);
        if rho > self.radial {
            let s = self.radial / rho;
            x[0] *= s;
            x[1] *= s;
        }
        x[2] = x[2].clamp(self.z0, self.z1);
    }
}
