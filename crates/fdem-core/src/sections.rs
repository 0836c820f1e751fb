//! A checksummed binary file of named sections: arrays of `f64` and UTF-8 texts, for
//! state that must come back bit for bit (a run's checkpoint).
//!
//! ```text
//! offset  size        content
//! 0       8           magic (the caller's, 8 bytes)
//! 8       4           format version, u32 little-endian (the caller's)
//! 12      8           section count S, u64 LE
//!         S x         per section: name length u32 LE, name (UTF-8), kind u8 (0 numbers,
//!                     1 text), length u64 LE (numbers or bytes), the data (f64 LE bits,
//!                     or the text's bytes)
//! end-8   8           FNV-1a 64-bit checksum of every byte before it, u64 LE
//! ```
//! Numbers are stored as their IEEE-754 bits (NaN and infinities included), so a value
//! read back is the value written. The file is written through [`crate::fs::AtomicFile`]:
//! a reader finds the previous complete file or the new one, never a mixture.

use crate::fs::write_atomically;
use crate::hash::Fnv1a;
use std::collections::BTreeMap;
use std::path::Path;

/// One section's data.
#[derive(Clone, Debug, PartialEq)]
enum Data {
    Numbers(Vec<f64>),
    Text(String),
}

/// Named sections, written and read as one file ([`Sections::write`], [`Sections::read`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sections {
    entries: BTreeMap<String, Data>,
}

impl Sections {
    /// No sections.
    pub fn new() -> Self {
        Sections::default()
    }

    /// Sets the numbers of section `name`.
    pub fn put_numbers(&mut self, name: &str, values: Vec<f64>) {
        self.entries.insert(name.into(), Data::Numbers(values));
    }

    /// Sets the text of section `name`.
    pub fn put_text(&mut self, name: &str, text: String) {
        self.entries.insert(name.into(), Data::Text(text));
    }

    /// The numbers of section `name`.
    ///
    /// # Errors
    /// No such section, or a text section, as a message naming it.
    pub fn numbers(&self, name: &str) -> Result<&[f64], String> {
        match self.entries.get(name) {
            Some(Data::Numbers(v)) => Ok(v),
            Some(Data::Text(_)) => Err(format!("section `{name}` holds text, not numbers")),
            None => Err(format!("section `{name}` is missing")),
        }
    }

    /// The numbers of section `name`, which must be `n` of them.
    ///
    /// # Errors
    /// As [`Sections::numbers`], or another count.
    pub fn numbers_of(&self, name: &str, n: usize) -> Result<&[f64], String> {
        let v = self.numbers(name)?;
        if v.len() == n {
            Ok(v)
        } else {
            Err(format!(
                "section `{name}` holds {} numbers, not {n}",
                v.len()
            ))
        }
    }

    /// The text of section `name`.
    ///
    /// # Errors
    /// No such section, or a numbers section, as a message naming it.
    pub fn text(&self, name: &str) -> Result<&str, String> {
        match self.entries.get(name) {
            Some(Data::Text(t)) => Ok(t),
            Some(Data::Numbers(_)) => Err(format!("section `{name}` holds numbers, not text")),
            None => Err(format!("section `{name}` is missing")),
        }
    }

    /// Writes the sections to `path` atomically, after `magic` and `version`.
    ///
    /// # Errors
    /// Any failure to create, write or rename the file (nothing is left under either name).
    pub fn write(&self, path: &Path, magic: &[u8; 8], version: u32) -> std::io::Result<()> {
        let mut bytes = Vec::new();
        bytes.extend_from_slice(magic);
        bytes.extend_from_slice(&version.to_le_bytes());
        bytes.extend_from_slice(&(self.entries.len() as u64).to_le_bytes());
        for (name, data) in &self.entries {
            bytes.extend_from_slice(&(name.len() as u32).to_le_bytes());
            bytes.extend_from_slice(name.as_bytes());
            match data {
                Data::Numbers(v) => {
                    bytes.push(0);
                    bytes.extend_from_slice(&(v.len() as u64).to_le_bytes());
                    bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
                }
                Data::Text(t) => {
                    bytes.push(1);
                    bytes.extend_from_slice(&(t.len() as u64).to_le_bytes());
                    bytes.extend_from_slice(t.as_bytes());
                }
            }
        }
        let sum = Fnv1a::of(&bytes);
        bytes.extend_from_slice(&sum.to_le_bytes());
        write_atomically(path, bytes)
    }

    /// Reads a file written by [`Sections::write`] with the same `magic` and `version`.
    ///
    /// # Errors
    /// A message saying what is wrong: the file cannot be read, another magic or version,
    /// a checksum that fails (a damaged or cut file), or a layout that does not parse.
    pub fn read(path: &Path, magic: &[u8; 8], version: u32) -> Result<Sections, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot be read: {e}"))?;
        if bytes.len() < 28 || &bytes[..8] != magic {
            return Err(format!(
                "is not a {} file",
                String::from_utf8_lossy(magic).trim_end()
            ));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let stored = u64::from_le_bytes(tail.try_into().map_err(|_| "is cut short")?);
        if Fnv1a::of(body) != stored {
            return Err("fails its checksum (damaged or cut short)".into());
        }
        let mut r = Reader { bytes: body, at: 8 };
        let found = u32::from_le_bytes(r.take(4)?.try_into().map_err(|_| "bad version")?);
        if found != version {
            return Err(format!(
                "has format version {found}; this build reads version {version}"
            ));
        }
        let count = r.u64()?;
        let mut sections = Sections::new();
        for _ in 0..count {
            let len = u32::from_le_bytes(r.take(4)?.try_into().map_err(|_| "bad name")?);
            let name = std::str::from_utf8(r.take(len as usize)?)
                .map_err(|_| "holds a section name that is not UTF-8")?
                .to_string();
            let kind = r.take(1)?[0];
            let n = usize::try_from(r.u64()?).map_err(|_| "holds a section too long")?;
            match kind {
                0 => {
                    let data = r.take(n.checked_mul(8).ok_or("holds a section too long")?)?;
                    let v = data
                        .chunks_exact(8)
                        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                        .collect();
                    sections.put_numbers(&name, v);
                }
                1 => {
                    let text = std::str::from_utf8(r.take(n)?)
                        .map_err(|_| format!("section `{name}` is not UTF-8"))?;
                    sections.put_text(&name, text.to_string());
                }
                k => return Err(format!("section `{name}` has an unknown kind {k}")),
            }
        }
        if r.at != body.len() {
            return Err("has bytes after its last section".into());
        }
        Ok(sections)
    }
}

/// A cursor over the bytes of a file being read.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or("is cut short")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().map_err(|_| "is cut short")?,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAGIC: &[u8; 8] = b"TESTSECT";

    #[test]
    fn sections_come_back_bit_for_bit_and_damage_is_found() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.bin");
        let mut s = Sections::new();
        let values = vec![0.1, -0.0, f64::NAN, f64::INFINITY, 5e-324, 1e308];
        s.put_numbers("a.values", values.clone());
        s.put_text("b.text", "peak, ünïcode\n".into());
        s.put_numbers("empty", Vec::new());
        s.write(&path, MAGIC, 3).unwrap();
        let back = Sections::read(&path, MAGIC, 3).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(back.numbers("a.values").unwrap()), bits(&values));
        assert_eq!(back.text("b.text").unwrap(), "peak, ünïcode\n");
        assert!(back.numbers_of("empty", 0).unwrap().is_empty());
        assert!(
            back.numbers_of("a.values", 5)
                .unwrap_err()
                .contains("not 5")
        );
        assert!(back.text("a.values").unwrap_err().contains("numbers"));
        assert!(back.numbers("c").unwrap_err().contains("missing"));
        assert!(
            Sections::read(&path, MAGIC, 4)
                .unwrap_err()
                .contains("version 3")
        );
        assert!(
            Sections::read(&path, b"OTHERMAG", 3)
                .unwrap_err()
                .contains("is not")
        );
        // Every single-byte change and every cut is found.
        let bytes = std::fs::read(&path).unwrap();
        for i in (0..bytes.len()).step_by(7) {
            let mut b = bytes.clone();
            b[i] ^= 0x10;
            std::fs::write(&path, &b).unwrap();
            assert!(Sections::read(&path, MAGIC, 3).is_err(), "byte {i}");
            std::fs::write(&path, &bytes[..i]).unwrap();
            assert!(Sections::read(&path, MAGIC, 3).is_err(), "cut at {i}");
        }
    }
}
