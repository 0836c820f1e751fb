//! The prepared-specimen file: a versioned binary format with a TOML header
//! (docs/SPECIMENS.md, "Specimen files").
//!
//! ```text
//! offset  size          content
//! 0       8             magic "FDEMSPEC"
//! 8       4             format version, u32 little-endian (FORMAT_VERSION)
//! 12      8             header length L in bytes, u64 LE
//! 20      L             header: UTF-8 TOML (format, versions, [specimen], [report])
//! 20+L    8 x 4         particle count P, node count N, history count K, rigid
//!                       count R (u64 LE)
//!         8 x 3         dt (f64), time (f64), step (u64)
//!         P x 8 x 8     per particle: diameter, centre x y z, quaternion w x y z (f64)
//!         P x 8         per particle: size class (u64)
//!         N x 3 x 8     positions (f64)
//!         N x 3 x 8     velocities (f64)
//!         K x 5 x 8     history: node (u64), counterpart (u64: body id, or 2^32 + wall
//!                       index), tangential displacement x y z (f64)
//!         R x 13 x 8    rigid particles in body order: centre of mass, its velocity,
//!                       orientation w x y z, body-frame angular momentum (f64)
//! end-8   8             FNV-1a 64-bit checksum of every byte before it (u64 LE)
//! ```
//! Numbers are stored as their IEEE-754 bits, so a reload is exact. The file is written
//! to `NAME.part` and renamed when complete. Version 1 (before rigid particles) had no
//! rigid count and no rigid block; it is still read.

use crate::placement::PlacedParticle;
use crate::prepare::{PreparationReport, PreparedSpecimen, Snapshot};
use crate::{SpecimenSpec, TriaxialError};
use fdem_contact::Counterpart;
use fdem_core::fs::AtomicFile;
use fdem_core::hash::Fnv1a;
use fdem_solver::RigidState;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The eight bytes every specimen file starts with.
pub const MAGIC: &[u8; 8] = b"FDEMSPEC";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 2;
/// The oldest format version this build reads.
const OLDEST_VERSION: u32 = 1;
/// Bytes before the header text.
const PREAMBLE: usize = 20;
/// Bytes of the fixed-size block after the header (counts, dt, time, step) of `version`.
const fn fixed_size(version: u32) -> usize {
    if version >= 2 { 56 } else { 48 }
}
/// Numbers of one rigid particle's state.
const RIGID_VALUES: u64 = 13;

/// The TOML header of a specimen file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    format: String,
    format_version: u32,
    fdem_version: String,
    specimen: SpecimenSpec,
    report: PreparationReport,
}

/// What a saved specimen file is to a definition ([`PreparedSpecimen::cached`]).
#[derive(Debug)]
pub enum Cached {
    /// A preparation of the definition, ready to test.
    Reusable(Box<PreparedSpecimen>),
    /// A preparation of another definition.
    Other,
    /// A file that does not load (damaged, another format), with the reason.
    Unreadable(TriaxialError),
    /// No file.
    Missing,
}

/// A writer that checksums what it writes.
struct Checked<W: Write> {
    inner: W,
    hash: Fnv1a,
}

impl<W: Write> Checked<W> {
    fn put(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.hash.update(bytes);
        self.inner.write_all(bytes)
    }
    fn u64(&mut self, v: u64) -> std::io::Result<()> {
        self.put(&v.to_le_bytes())
    }
    fn f64(&mut self, v: f64) -> std::io::Result<()> {
        self.put(&v.to_le_bytes())
    }
}

impl PreparedSpecimen {
    /// Writes the specimen to `path` (atomically: `path.part`, then a rename).
    pub fn save(&self, path: &Path) -> Result<(), TriaxialError> {
        let header = Header {
            format: "fdem-specimen".into(),
            format_version: FORMAT_VERSION,
            fdem_version: env!("CARGO_PKG_VERSION").into(),
            specimen: self.spec.clone(),
            report: self.report.clone(),
        };
        let text = toml::to_string(&header).map_err(|e| {
            TriaxialError::file(path, format!("cannot write the header as TOML: {e}"))
        })?;
        let file = AtomicFile::create(path).map_err(|e| TriaxialError::io("creating", path, e))?;
        let mut w = Checked {
            inner: file,
            hash: Fnv1a::new(),
        };
        let s = &self.state;
        let result = (|| -> std::io::Result<()> {
            w.put(MAGIC)?;
            w.put(&FORMAT_VERSION.to_le_bytes())?;
            w.u64(text.len() as u64)?;
            w.put(text.as_bytes())?;
            w.u64(self.particles.len() as u64)?;
            w.u64(s.positions.len() as u64)?;
            w.u64(s.history.len() as u64)?;
            w.u64(s.rigid.len() as u64)?;
            w.f64(self.dt)?;
            w.f64(s.time)?;
            w.u64(s.step)?;
            for p in &self.particles {
                w.f64(p.diameter)?;
                for v in p.center {
                    w.f64(v)?;
                }
                for v in p.orientation {
                    w.f64(v)?;
                }
            }
            for p in &self.particles {
                w.u64(p.class as u64)?;
            }
            for x in s.positions.iter().chain(&s.velocities) {
                for &v in x {
                    w.f64(v)?;
                }
            }
            for &(node, c, d) in &s.history {
                w.u64(node as u64)?;
                w.u64(c.code())?;
                for v in d {
                    w.f64(v)?;
                }
            }
            for r in &s.rigid {
                let values = r
                    .position
                    .iter()
                    .chain(&r.velocity)
                    .chain(&r.orientation)
                    .chain(&r.body_momentum);
                for &v in values {
                    w.f64(v)?;
                }
            }
            let sum = w.hash.0;
            w.inner.write_all(&sum.to_le_bytes())
        })();
        // On an error the unfinished file is dropped, which removes the temporary.
        result
            .and_then(|()| w.inner.finish())
            .map_err(|e| TriaxialError::io("writing", path, e))
    }

    /// What the specimen file at `path` is to the definition `spec`: a preparation of it
    /// (equal [`SpecimenSpec::preparation_key`]s; returned with `spec` as its definition,
    /// so the test's own settings apply), another specimen's, unreadable, or missing.
    pub fn cached(path: &Path, spec: &SpecimenSpec) -> Cached {
        if !path.exists() {
            return Cached::Missing;
        }
        match PreparedSpecimen::load(path) {
            Ok(s) if s.spec.preparation_key() == spec.preparation_key() => {
                Cached::Reusable(Box::new(PreparedSpecimen {
                    spec: spec.clone(),
                    ..s
                }))
            }
            Ok(_) => Cached::Other,
            Err(e) => Cached::Unreadable(e),
        }
    }

    /// Reads a specimen file written by [`PreparedSpecimen::save`], refusing a file of
    /// another format version, a truncated or corrupted one (checksum) and one whose
    /// definition or counts do not hold.
    pub fn load(path: &Path) -> Result<PreparedSpecimen, TriaxialError> {
        let bytes = std::fs::read(path).map_err(|e| TriaxialError::io("reading", path, e))?;
        check_magic(&bytes, path)?;
        if !checksum_holds(&bytes) {
            return Err(diagnose(&bytes, path));
        }
        let version = check_version(&bytes, path)?;
        let layout = Layout::read(&bytes, version, path)?;
        let header = read_header(&bytes[PREAMBLE..layout.body_start], version, path)?;
        let mut r = Reader {
            bytes: &bytes,
            at: layout.data_start,
        };
        let (dt, particles, state) = read_body(&mut r, &layout, path)?;

        // The file must describe the specimen its definition implies.
        let counts = header.specimen.counts()?;
        let (n_particles, n_nodes) = (layout.particles, layout.nodes);
        if counts.particles != n_particles || counts.nodes != n_nodes {
            return Err(TriaxialError::file(
                path,
                format!(
                    "holds {n_particles} particles and {n_nodes} nodes, but its definition \
                     implies {} and {}",
                    counts.particles, counts.nodes
                ),
            ));
        }
        let rigid_expected = counts.rigid_particles;
        if layout.rigid != rigid_expected {
            return Err(TriaxialError::file(
                path,
                format!(
                    "holds {} rigid particle states, but its definition (model = \"{}\") \
                     implies {rigid_expected}",
                    layout.rigid,
                    header.specimen.model.name()
                ),
            ));
        }
        Ok(PreparedSpecimen {
            spec: header.specimen,
            particles,
            dt,
            state,
            report: header.report,
        })
    }
}

/// Refuses a file that does not start with [`MAGIC`] (or, shorter than it, is not its
/// beginning) and one too short to hold the preamble and a checksum.
fn check_magic(bytes: &[u8], path: &Path) -> Result<(), TriaxialError> {
    let bad = |m: String| TriaxialError::file(path, m);
    let start = &bytes[..bytes.len().min(MAGIC.len())];
    if !MAGIC.starts_with(start) {
        return Err(bad(
            "not an fdem specimen file (it does not start with FDEMSPEC); write one with \
             `fdem specimen --prepare --out FILE`"
                .into(),
        ));
    }
    let shortest = PREAMBLE + CHECKSUM;
    if bytes.len() < shortest {
        return Err(bad(format!(
            "truncated: {} bytes, less than the {shortest} of the preamble and the checksum; \
             the file is incomplete (an interrupted copy?)",
            bytes.len()
        )));
    }
    Ok(())
}

/// Refuses a file of a format version this build does not read; returns the version.
fn check_version(bytes: &[u8], path: &Path) -> Result<u32, TriaxialError> {
    let version = stored_version(bytes);
    if !(OLDEST_VERSION..=FORMAT_VERSION).contains(&version) {
        return Err(TriaxialError::file(
            path,
            format!(
                "specimen format version {version}, but this fdem ({}) reads versions \
                 {OLDEST_VERSION} to {FORMAT_VERSION}; prepare the specimen again with this version",
                env!("CARGO_PKG_VERSION")
            ),
        ));
    }
    Ok(version)
}

/// The format version in the preamble (the length was checked).
fn stored_version(bytes: &[u8]) -> u32 {
    u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]])
}

/// Where the parts of a specimen file lie: the end of the header and the stored counts.
struct Layout {
    /// Offset of the counts, just after the header text.
    body_start: usize,
    /// Offset of what follows the counts (dt, time, step, ...).
    data_start: usize,
    particles: u64,
    nodes: u64,
    history: u64,
    rigid: u64,
}

impl Layout {
    /// Reads the header length and the counts, and checks that the file's size is the one
    /// they imply.
    fn read(bytes: &[u8], version: u32, path: &Path) -> Result<Layout, TriaxialError> {
        let bad = |m: String| TriaxialError::file(path, m);
        let mut r = Reader { bytes, at: 12 };
        let truncated = |needed: u64| {
            bad(format!(
                "truncated: {} bytes, but the layout needs at least {needed}; the file is \
                 incomplete (an interrupted copy?)",
                bytes.len()
            ))
        };
        let header_len = r.u64().ok_or_else(|| truncated(PREAMBLE as u64))?;
        let body_start = (PREAMBLE as u64).saturating_add(header_len);
        let fixed_end = body_start.saturating_add(fixed_size(version) as u64 + 8);
        if (bytes.len() as u64) < fixed_end {
            return Err(truncated(fixed_end));
        }
        r.at = body_start as usize;
        let (n_particles, n_nodes, n_history) = (
            r.u64().unwrap_or(0),
            r.u64().unwrap_or(0),
            r.u64().unwrap_or(0),
        );
        let n_rigid = if version >= 2 {
            r.u64().unwrap_or(0)
        } else {
            0
        };
        let expected = [
            (n_particles, 9 * 8u64),
            (n_nodes, 6 * 8),
            (n_history, 5 * 8),
            (n_rigid, RIGID_VALUES * 8),
        ]
        .iter()
        .try_fold(fixed_end, |acc, &(n, size)| {
            n.checked_mul(size).and_then(|b| acc.checked_add(b))
        })
        .ok_or_else(|| bad("corrupted: the counts in the file overflow".into()))?;
        if (bytes.len() as u64) < expected {
            return Err(truncated(expected));
        }
        if (bytes.len() as u64) > expected {
            return Err(bad(format!(
                "corrupted: {} bytes, {} more than the layout holds",
                bytes.len(),
                bytes.len() as u64 - expected
            )));
        }
        Ok(Layout {
            body_start: body_start as usize,
            data_start: r.at,
            particles: n_particles,
            nodes: n_nodes,
            history: n_history,
            rigid: n_rigid,
        })
    }
}

/// Bytes of the checksum at the end of the file.
const CHECKSUM: usize = 8;

/// Whether the last eight bytes are the checksum of the bytes before them.
fn checksum_holds(bytes: &[u8]) -> bool {
    let end = bytes.len() - CHECKSUM;
    let mut hash = Fnv1a::new();
    hash.update(&bytes[..end]);
    let mut stored = [0u8; CHECKSUM];
    stored.copy_from_slice(&bytes[end..]);
    hash.0 == u64::from_le_bytes(stored)
}

/// Says why a file whose checksum does not hold is damaged. A truncated file is the
/// beginning of a whole one, so it is called truncated only when everything it holds is
/// consistent with that: its header whole text (or text cut short), its stored counts
/// those its definition implies, its size short of the layout, and the history entries
/// present valid ones. Anything else is a changed byte.
fn diagnose(bytes: &[u8], path: &Path) -> TriaxialError {
    let len = bytes.len() as u64;
    let corrupted = |what: String| {
        TriaxialError::file(
            path,
            format!(
                "corrupted: the checksum does not match the contents ({what}); prepare the \
                 specimen again or restore the file from a good copy"
            ),
        )
    };
    let truncated = |needed: u64| {
        TriaxialError::file(
            path,
            format!(
                "truncated: {len} bytes, but the layout needs {needed}; the file is incomplete \
                 (an interrupted copy?)"
            ),
        )
    };
    let version = stored_version(bytes);
    if !(OLDEST_VERSION..=FORMAT_VERSION).contains(&version) {
        return corrupted(format!("format version {version}"));
    }
    let mut r = Reader { bytes, at: 12 };
    let header_len = r.u64().unwrap_or(0);
    let header_end = (PREAMBLE as u64).saturating_add(header_len);
    let fixed_end = header_end.saturating_add(fixed_size(version) as u64);
    if header_end > len {
        // A header cut short is text; a zero byte in what follows the preamble is binary
        // data read as header, so the header length was changed.
        return if bytes[PREAMBLE..].contains(&0) {
            corrupted(format!("a header length of {header_len} bytes"))
        } else {
            truncated(fixed_end.saturating_add(CHECKSUM as u64))
        };
    }
    let header = match read_header(&bytes[PREAMBLE..header_end as usize], version, path) {
        Ok(h) => h,
        Err(e) => return corrupted(format!("the header: {e}")),
    };
    let counts = match header.specimen.counts() {
        Ok(c) => c,
        Err(e) => return corrupted(format!("its definition: {e}")),
    };
    r.at = header_end as usize;
    let stored: Vec<Option<u64>> = (0..4).map(|_| r.u64()).collect();
    let [Some(particles), Some(nodes), Some(history), rigid] = stored[..] else {
        return truncated(fixed_end.saturating_add(CHECKSUM as u64));
    };
    let rigid = if version >= 2 { rigid } else { Some(0) };
    let Some(rigid) = rigid else {
        return truncated(fixed_end.saturating_add(CHECKSUM as u64));
    };
    if (particles, nodes, rigid) != (counts.particles, counts.nodes, counts.rigid_particles) {
        return corrupted(format!(
            "it stores {particles} particles, {nodes} nodes and {rigid} rigid states, but its \
             definition implies {}, {} and {}",
            counts.particles, counts.nodes, counts.rigid_particles
        ));
    }
    // The particle and node blocks have the sizes of the definition's counts.
    let history_start = fixed_end
        .saturating_add(particles.saturating_mul(9 * 8))
        .saturating_add(nodes.saturating_mul(6 * 8));
    let rest = rigid
        .saturating_mul(RIGID_VALUES * 8)
        .saturating_add(history_start)
        .saturating_add(CHECKSUM as u64);
    let expected = history.checked_mul(5 * 8).and_then(|h| h.checked_add(rest));
    let Some(expected) = expected else {
        return corrupted(format!("a history count of {history}"));
    };
    match expected.cmp(&len) {
        std::cmp::Ordering::Greater => {
            // The entries present must be valid ones (a node of the file, a counterpart
            // code); a history count changed upwards reads what follows as entries.
            r.at = history_start.min(len) as usize;
            for _ in 0..history {
                let Some(node) = r.u64() else { break };
                let code = r.u64().unwrap_or(0);
                if node >= nodes || code >> 32 > 1 {
                    return corrupted(format!(
                        "a history count of {history} disagrees with the entries stored"
                    ));
                }
                if r.at + 3 * 8 > bytes.len() {
                    break;
                }
                r.at += 3 * 8;
            }
            truncated(expected)
        }
        std::cmp::Ordering::Less => corrupted(format!(
            "{len} bytes, {} more than the layout holds",
            len - expected
        )),
        std::cmp::Ordering::Equal => corrupted("the layout is whole, so bytes were changed".into()),
    }
}

/// Parses the TOML header and checks its format and the specimen definition.
fn read_header(header_bytes: &[u8], version: u32, path: &Path) -> Result<Header, TriaxialError> {
    let bad = |m: String| TriaxialError::file(path, m);
    let text = std::str::from_utf8(header_bytes)
        .map_err(|_| bad("corrupted: the header is not UTF-8".into()))?;
    let header: Header = toml::from_str(text)
        .map_err(|e| bad(format!("the header does not parse: {}", e.message())))?;
    if header.format != "fdem-specimen" || header.format_version != version {
        return Err(bad(format!(
            "the header says format `{}` version {}, not fdem-specimen version {version}",
            header.format, header.format_version
        )));
    }
    let origin = path.display().to_string();
    header.specimen.validate(&origin)?;
    Ok(header)
}

/// Reads what follows the counts: dt, the particles and the state (time, step, positions,
/// velocities, tangential history).
fn read_body(
    r: &mut Reader<'_>,
    layout: &Layout,
    path: &Path,
) -> Result<(f64, Vec<PlacedParticle>, Snapshot), TriaxialError> {
    let dt = r.f64().unwrap_or(f64::NAN);
    let time = r.f64().unwrap_or(f64::NAN);
    let step = r.u64().unwrap_or(0);
    let mut particles = Vec::with_capacity(layout.particles as usize);
    for _ in 0..layout.particles {
        let v: [f64; 8] = std::array::from_fn(|_| r.f64().unwrap_or(f64::NAN));
        particles.push(PlacedParticle {
            diameter: v[0],
            center: [v[1], v[2], v[3]],
            orientation: [v[4], v[5], v[6], v[7]],
            class: 0,
        });
    }
    for p in &mut particles {
        p.class = r.u64().unwrap_or(0) as usize;
    }
    let mut vectors = |n: u64| -> Vec<[f64; 3]> {
        (0..n)
            .map(|_| std::array::from_fn(|_| r.f64().unwrap_or(f64::NAN)))
            .collect()
    };
    let positions = vectors(layout.nodes);
    let velocities = vectors(layout.nodes);
    let history = read_history(r, layout.history, path)?;
    let rigid = (0..layout.rigid)
        .map(|_| {
            let v: [f64; 13] = std::array::from_fn(|_| r.f64().unwrap_or(f64::NAN));
            RigidState {
                position: [v[0], v[1], v[2]],
                velocity: [v[3], v[4], v[5]],
                orientation: [v[6], v[7], v[8], v[9]],
                body_momentum: [v[10], v[11], v[12]],
            }
        })
        .collect();
    let state = Snapshot {
        positions,
        velocities,
        history,
        rigid,
        time,
        step,
    };
    Ok((dt, particles, state))
}

/// Reads `n` history entries: node, counterpart code, tangential displacement.
fn read_history(
    r: &mut Reader<'_>,
    n: u64,
    path: &Path,
) -> Result<Vec<(usize, Counterpart, [f64; 3])>, TriaxialError> {
    let mut history = Vec::with_capacity(n as usize);
    for i in 0..n {
        let node = r.u64().unwrap_or(0);
        let code = r.u64().unwrap_or(0);
        let d: [f64; 3] = std::array::from_fn(|_| r.f64().unwrap_or(f64::NAN));
        let Some(counterpart) = Counterpart::from_code(code) else {
            return Err(TriaxialError::file(
                path,
                format!("corrupted: history entry {i} has counterpart code {code}"),
            ));
        };
        history.push((node as usize, counterpart, d));
    }
    Ok(history)
}

/// Little-endian reader over a byte slice whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take8(&mut self) -> Option<[u8; 8]> {
        let b = self.bytes.get(self.at..self.at + 8)?;
        self.at += 8;
        let mut out = [0u8; 8];
        out.copy_from_slice(b);
        Some(out)
    }
    fn u64(&mut self) -> Option<u64> {
        self.take8().map(u64::from_le_bytes)
    }
    fn f64(&mut self) -> Option<f64> {
        self.take8().map(f64::from_le_bytes)
    }
}
