//! Random loose placement: non-overlapping spheres in a vertical cylinder, largest first,
//! found through a uniform grid (each test looks at the 27 cells around a candidate, never
//! at all placed particles), with uniformly random orientations.

use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};

/// Random positions tried for one particle before the column is declared too full.
pub const MAX_ATTEMPTS: usize = 20_000;

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

/// Why a placement failed: the particle (in placement order) that found no room.
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
/// `clearance` inside the cylinder and its ends. Diameters are placed from the largest to
/// the smallest (ties in the given order); the result is in placement order.
///
/// Deterministic for a given `seed`. The grid cell is the largest diameter plus the
/// clearance, so any sphere that could overlap a candidate is in one of the 27 cells
/// around it.
pub fn place_spheres(
    diameters: &[(f64, usize)],
    column: &Column,
    clearance: f64,
    seed: u64,
) -> Result<Vec<PlacedParticle>, NoRoom> {
    let mut order: Vec<usize> = (0..diameters.len()).collect();
    order.sort_by(|&a, &b| diameters[b].0.total_cmp(&diameters[a].0).then(a.cmp(&b)));
    let d_max = diameters.iter().map(|d| d.0).fold(0.0, f64::max);
    let mut grid = Grid::new(column, d_max + clearance);
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut placed: Vec<PlacedParticle> = Vec::with_capacity(diameters.len());
    for (n, &i) in order.iter().enumerate() {
        let (d, class) = diameters[i];
        let r = 0.5 * d;
        let radial = column.radius - r - clearance;
        let (z0, z1) = (column.bottom + r + clearance, column.top - r - clearance);
        if radial < 0.0 || z1 < z0 {
            return Err(NoRoom {
                particle: n,
                diameter: d,
            });
        }
        let mut found = None;
        for _ in 0..MAX_ATTEMPTS {
            // Uniform in the disc of radius `radial` and in [z0, z1].
            let rho = radial * rng.random_range(0.0f64..1.0).sqrt();
            let theta = std::f64::consts::TAU * rng.random_range(0.0f64..1.0);
            let z = if z1 > z0 {
                rng.random_range(z0..z1)
            } else {
                z0
            };
            let x = [rho * theta.cos(), rho * theta.sin(), z];
            let free = grid.all_near(x, |id| {
                let o = &placed[id as usize];
                let reach = r + 0.5 * o.diameter + clearance;
                let dx = [x[0] - o.center[0], x[1] - o.center[1], x[2] - o.center[2]];
                dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2] >= reach * reach
            });
            if free {
                found = Some(x);
                break;
            }
        }
        let Some(center) = found else {
            return Err(NoRoom {
                particle: n,
                diameter: d,
            });
        };
        grid.insert(center, placed.len() as u32);
        placed.push(PlacedParticle {
            diameter: d,
            center,
            orientation: random_rotation(&mut rng),
            class,
        });
    }
    Ok(placed)
}
