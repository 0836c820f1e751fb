//! Rigid walls: planes and cylinders moving at a prescribed constant velocity.

use serde::{Deserialize, Serialize};

use crate::ContactError;
use crate::vec3::{add, dot, is_finite, norm, scale, sub};

/// Geometry of a rigid wall at time 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum WallShape {
    /// An infinite plane. Particles live on the side `normal` points to; a node on the
    /// other side penetrates by its distance to the plane.
    Plane {
        /// A point of the plane at time 0 (m).
        point: [f64; 3],
        /// Normal towards the particles (any non-zero length; normalised at set-up).
        normal: [f64; 3],
    },
    /// An infinite circular cylinder. Particles live inside; a node farther than `radius`
    /// from the axis penetrates by the excess.
    Cylinder {
        /// A point of the axis at time 0 (m).
        axis_point: [f64; 3],
        /// Axis direction (any non-zero length; normalised at set-up).
        axis: [f64; 3],
        /// Inner radius (m), finite and > 0.
        radius: f64,
    },
}

/// A rigid wall: a shape translated at a constant prescribed velocity, so that its position
/// at time `t` is the initial one plus `velocity * t`. It acts on the particles' surface
/// nodes with the same law as a face ([`crate::evaluate_law`]), the wall being the face.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    /// Shape at time 0.
    pub shape: WallShape,
    /// Prescribed translation velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
}

impl Wall {
    /// A fixed plane through `point` with particles on the side of `normal`.
    pub fn plane(point: [f64; 3], normal: [f64; 3]) -> Wall {
        Wall {
            shape: WallShape::Plane { point, normal },
            velocity: [0.0; 3],
        }
    }

    /// A fixed cylinder of the given axis and inner radius with particles inside.
    pub fn cylinder(axis_point: [f64; 3], axis: [f64; 3], radius: f64) -> Wall {
        Wall {
            shape: WallShape::Cylinder {
                axis_point,
                axis,
                radius,
            },
            velocity: [0.0; 3],
        }
    }

    /// The same wall moving at `velocity` (m/s).
    pub fn moving(self, velocity: [f64; 3]) -> Wall {
        Wall { velocity, ..self }
    }

    /// Checks the wall and returns it with a unit normal or axis.
    ///
    /// # Errors
    /// [`ContactError::InvalidWall`] naming what is wrong.
    pub fn normalised(&self, index: usize) -> Result<Wall, ContactError> {
        let bad = |reason: String| ContactError::InvalidWall {
            wall: index,
            reason,
        };
        if !is_finite(self.velocity) {
            return Err(bad(format!(
                "velocity {:?} has a non-finite component; give three finite numbers (m/s)",
                self.velocity
            )));
        }
        let unit = |v: [f64; 3], what: &str| {
            let l = norm(v);
            if is_finite(v) && l > 0.0 && l.is_finite() {
                Ok(scale(v, 1.0 / l))
            } else {
                Err(bad(format!(
                    "{what} {v:?} is zero or not finite; give a non-zero finite direction"
                )))
            }
        };
        let shape = match self.shape {
            WallShape::Plane { point, normal } => {
                if !is_finite(point) {
                    return Err(bad(format!("plane point {point:?} is not finite")));
                }
                WallShape::Plane {
                    point,
                    normal: unit(normal, "plane normal")?,
                }
            }
            WallShape::Cylinder {
                axis_point,
                axis,
                radius,
            } => {
                if !is_finite(axis_point) {
                    return Err(bad(format!(
                        "cylinder axis point {axis_point:?} is not finite"
                    )));
                }
                if !(radius.is_finite() && radius > 0.0) {
                    return Err(bad(format!(
                        "cylinder radius {} is not finite and > 0; give the inner radius in metres",
                        fdem_core::number::Number(radius)
                    )));
                }
                WallShape::Cylinder {
                    axis_point,
                    axis: unit(axis, "cylinder axis")?,
                    radius,
                }
            }
        };
        Ok(Wall {
            shape,
            velocity: self.velocity,
        })
    }

    /// The shape translated to time `t` (position = initial + velocity * t).
    pub fn shape_at(&self, time: f64) -> WallShape {
        self.shape.translated(scale(self.velocity, time))
    }
}

impl WallShape {
    /// The shape moved by `shift` (m).
    pub fn translated(self, shift: [f64; 3]) -> WallShape {
        match self {
            WallShape::Plane { point, normal } => WallShape::Plane {
                point: add(point, shift),
                normal,
            },
            WallShape::Cylinder {
                axis_point,
                axis,
                radius,
            } => WallShape::Cylinder {
                axis_point: add(axis_point, shift),
                axis,
                radius,
            },
        }
    }
}

/// Signed distance of `x` from a wall shape with a unit normal/axis, positive on the
/// particles' side, and the unit normal towards the particles at the closest wall point.
/// `None` for a node on the cylinder axis (it cannot touch the cylinder).
#[inline]
pub(crate) fn wall_distance(shape: &WallShape, x: [f64; 3]) -> Option<(f64, [f64; 3])> {
    match *shape {
        WallShape::Plane { point, normal } => Some((dot(sub(x, point), normal), normal)),
        WallShape::Cylinder {
            axis_point,
            axis,
            radius,
        } => {
            let rel = sub(x, axis_point);
            let radial = sub(rel, scale(axis, dot(rel, axis)));
            let r = norm(radial);
            if r > 0.0 {
                Some((radius - r, scale(radial, -1.0 / r)))
            } else {
                None
            }
        }
    }
}
