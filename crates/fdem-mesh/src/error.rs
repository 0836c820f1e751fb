//! The crate's error type.

use std::path::PathBuf;

use crate::ElementOrder;
use fdem_core::number::Number;

/// Everything that can go wrong while building, placing or writing a mesh.
///
/// Every message says what was wrong and what would fix it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The icosahedron subdivision level is outside `0..=MAX_LEVEL`.
    #[error("subdivision level {level} is out of range 0..={max}; use a level from 0 to {max}")]
    LevelOutOfRange {
        /// The level that was asked for.
        level: u32,
        /// The largest supported level ([`crate::MAX_LEVEL`]).
        max: u32,
    },

    /// The number of concentric shells is outside `1..=MAX_SHELLS`.
    #[error("{shells} shells are out of range 1..={max}; use 1 to {max} shells")]
    ShellsOutOfRange {
        /// The number of shells that was asked for.
        shells: u32,
        /// The largest supported number ([`crate::MAX_SHELLS`]).
        max: u32,
    },

    /// The sphere diameter is zero, negative, infinite or NaN.
    #[error(
        "particle diameter {} is invalid; give a finite diameter greater than 0 (in metres)",
        Number(*.diameter)
    )]
    InvalidDiameter {
        /// The diameter that was given.
        diameter: f64,
    },

    /// Ellipsoid axes with a component that is zero, negative, infinite or NaN.
    #[error(
        "ellipsoid axes {axes:?} are invalid; give three finite numbers greater than 0 \
         (each relative to the diameter; [1, 1, 1] is the sphere)"
    )]
    InvalidAxes {
        /// The axes that were given.
        axes: [f64; 3],
    },

    /// A placement scale is zero, negative, infinite or NaN.
    #[error(
        "placement scale {} is invalid; give a finite scale greater than 0",
        Number(*.scale)
    )]
    InvalidScale {
        /// The scale that was given.
        scale: f64,
    },

    /// A placement rotation is not a finite unit quaternion.
    #[error(
        "placement rotation [w, x, y, z] = {rotation:?} is not a unit quaternion (norm {}); \
         give four finite numbers whose norm is 1 within 1e-6 (normalise it first)",
        Number(*.norm)
    )]
    InvalidRotation {
        /// The quaternion that was given, `[w, x, y, z]`.
        rotation: [f64; 4],
        /// Its Euclidean norm.
        norm: f64,
    },

    /// A placement translation has a non-finite component.
    #[error(
        "placement translation {translation:?} has a non-finite component; give three finite numbers"
    )]
    InvalidTranslation {
        /// The translation that was given.
        translation: [f64; 3],
    },

    /// An instance of one element order was pushed into an assembly of the other.
    #[error(
        "cannot add a {requested:?} mesh to an assembly of {existing:?} meshes; \
         mixed element orders are not supported: mesh every body with the same order"
    )]
    MixedOrder {
        /// The order of the bodies already in the assembly.
        existing: ElementOrder,
        /// The order of the rejected template.
        requested: ElementOrder,
    },

    /// The assembly already holds as many bodies as a `u32` body id can count.
    #[error(
        "the assembly already holds {bodies} bodies, the most a u32 body id can count; split the model"
    )]
    TooManyBodies {
        /// Number of bodies already in the assembly.
        bodies: usize,
    },

    /// A mesh's arrays are inconsistent (wrong lengths, indices out of range).
    #[error("invalid mesh: {reason}; build meshes with `sphere_mesh` or fix the arrays")]
    InvalidMesh {
        /// What was inconsistent.
        reason: String,
    },

    /// A VTU frame's arrays do not fit together.
    #[error("cannot write VTU frame: {reason}")]
    InvalidFrame {
        /// What was inconsistent, and how to fix it.
        reason: String,
    },

    /// A time in a ParaView collection is not finite.
    #[error("time {time} of PVD entry {index} is not finite; give finite times")]
    InvalidTime {
        /// Position of the entry in the list.
        index: usize,
        /// The time that was given.
        time: f64,
    },

    /// A file could not be created, written or renamed.
    #[error("could not write {path}: {source}; check that the directory exists and is writable")]
    Io {
        /// The file being written (its final path).
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },

    /// The output path has no file name (it is empty or ends in `..`).
    #[error("output path {path} has no file name; give a path such as `out/particle.vtu`")]
    NoFileName {
        /// The path that was given.
        path: PathBuf,
    },

    /// The VTK library failed to encode the data.
    #[error("could not encode VTK data for {path}: {message}")]
    Vtk {
        /// The file being written.
        path: PathBuf,
        /// The library's message.
        message: String,
    },
}
