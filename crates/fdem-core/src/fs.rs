//! Atomic file output: every file of the project is written under a temporary name in its
//! own directory and renamed to its final name when complete, so a reader never sees a
//! half-written file and an interrupted run leaves no truncated file under the final name.
//!
//! The temporary of `dir/NAME` is `dir/NAME.part` ([`partial_path`]), for every file. It
//! is flushed to disk before the rename and removed when writing fails. Two writers of
//! the same final path at the same time are not supported (they share the temporary).
//!
//! Errors are plain [`std::io::Error`]s; each crate maps them into its own error type,
//! naming the final path.

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// What is appended to a file's name to make the name of its temporary.
pub const PARTIAL_SUFFIX: &str = ".part";

/// The temporary of `path`: `NAME.part` in the same directory.
///
/// # Errors
/// [`io::ErrorKind::InvalidInput`] when `path` names no file (it is empty or ends in `..`).
pub fn partial_path(path: &Path) -> io::Result<PathBuf> {
    let Some(name) = path.file_name() else {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} names no file", path.display()),
        ));
    };
    let mut partial = OsString::from(name);
    partial.push(PARTIAL_SUFFIX);
    Ok(path.with_file_name(partial))
}

/// Writes `bytes` to `path` atomically: to [`partial_path`], flushed, then renamed.
///
/// # Errors
/// Any failure to create, write, flush or rename; the temporary is removed then.
pub fn write_atomically(path: &Path, bytes: impl AsRef<[u8]>) -> io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(bytes.as_ref())?;
    file.finish()
}

/// The temporaries being written, so that an exit that runs no destructors (a second
/// interrupt, which exits at once) can still remove them ([`remove_unfinished`]).
static UNFINISHED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn unfinished() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    UNFINISHED
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Removes the temporary of every [`AtomicFile`] still being written (best effort), for
/// a process about to exit without finishing them; returns how many there were.
pub fn remove_unfinished() -> usize {
    let partials = std::mem::take(&mut *unfinished());
    for p in &partials {
        let _ = std::fs::remove_file(p);
    }
    partials.len()
}

/// A file written piece by piece (rows of a time series, a binary record) under its
/// temporary name and renamed into place by [`AtomicFile::finish`].
///
/// Writes are buffered. Dropping the value without `finish` (an error, an interrupted
/// run that stops writing) removes the temporary, so nothing is left under either name.
#[derive(Debug)]
pub struct AtomicFile {
    writer: Option<BufWriter<File>>,
    partial: PathBuf,
    path: PathBuf,
}

impl AtomicFile {
    /// Creates (or truncates) the temporary of `path`.
    ///
    /// # Errors
    /// `path` names no file, or the temporary cannot be created.
    pub fn create(path: &Path) -> io::Result<Self> {
        let partial = partial_path(path)?;
        let file = File::create(&partial)?;
        unfinished().push(partial.clone());
        Ok(AtomicFile {
            writer: Some(BufWriter::new(file)),
            partial,
            path: path.to_path_buf(),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary being written.
    pub fn partial(&self) -> &Path {
        &self.partial
    }

    /// Flushes the buffer, syncs the file to disk and renames it to its final name.
    ///
    /// # Errors
    /// Any failure to flush, sync or rename; the temporary is removed then.
    pub fn finish(mut self) -> io::Result<()> {
        let result = self.commit();
        if result.is_err() {
            self.discard();
        }
        result
    }

    fn commit(&mut self) -> io::Result<()> {
        let writer = self.writer.take().ok_or_else(closed)?;
        let file = writer
            .into_inner()
            .map_err(io::IntoInnerError::into_error)?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&self.partial, &self.path)?;
        self.forget();
        Ok(())
    }

    fn discard(&mut self) {
        self.writer = None;
        // Best effort: the temporary may already be gone.
        let _ = std::fs::remove_file(&self.partial);
        self.forget();
    }

    /// Takes the temporary off the list of unfinished ones.
    fn forget(&self) {
        let mut list = unfinished();
        if let Some(i) = list.iter().position(|p| *p == self.partial) {
            list.swap_remove(i);
        }
    }

    fn writer(&mut self) -> io::Result<&mut BufWriter<File>> {
        self.writer.as_mut().ok_or_else(closed)
    }
}

fn closed() -> io::Error {
    io::Error::other("the file is already closed")
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer()?.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.writer()?.write_all(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.is_some() {
            self.discard();
        }
    }
}

/// Clears what an earlier run left in its output directory `dir`, so that a new run's
/// outputs are never mixed with an older one's: each of `files` (and its temporary), and
/// in each `(folder, prefix)` of `series` the files whose names start with `prefix` (the
/// numbered frames and snapshots of a series). Nothing else in `dir` is touched; missing
/// files and folders are fine.
///
/// # Errors
/// A file that exists but cannot be removed.
pub fn clear_outputs(dir: &Path, files: &[&str], series: &[(&str, &str)]) -> io::Result<()> {
    let remove = |path: &Path| match std::fs::remove_file(path) {
        Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    };
    for name in files {
        let path = dir.join(name);
        remove(&path)?;
        remove(&partial_path(&path)?)?;
    }
    for (folder, prefix) in series {
        let folder = dir.join(folder);
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries {
            let entry = entry?;
            if entry.file_name().to_string_lossy().starts_with(prefix) {
                remove(&entry.path())?;
            }
        }
    }
    Ok(())
}

/// The memory the operating system says new allocations can use (bytes): Linux's
/// `MemAvailable` of `/proc/meminfo`; `None` where it cannot be read.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn the_temporary_is_name_dot_part_next_to_the_file() {
        let p = partial_path(Path::new("out/contacts/nodes_000001.csv")).unwrap();
        assert_eq!(p, Path::new("out/contacts/nodes_000001.csv.part"));
        assert_eq!(partial_path(Path::new("a")).unwrap(), Path::new("a.part"));
        for bad in ["", "out/.."] {
            let e = partial_path(Path::new(bad)).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{bad:?}");
        }
    }

    #[test]
    fn write_replaces_the_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("summary.json");
        write_atomically(&path, "old").unwrap();
        write_atomically(&path, b"new\n").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new\n");
        assert_eq!(names(dir.path()), ["summary.json"]);
    }

    #[test]
    fn failures_leave_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing").join("f.csv");
        assert_eq!(
            write_atomically(&missing, "x").unwrap_err().kind(),
            io::ErrorKind::NotFound
        );
        // The final name is a directory: the rename fails, the temporary goes.
        let taken = dir.path().join("taken");
        std::fs::create_dir(&taken).unwrap();
        std::fs::write(taken.join("inside"), "x").unwrap();
        assert!(write_atomically(&taken, "x").is_err());
        assert_eq!(names(dir.path()), ["taken"]);
    }

    #[test]
    fn a_streamed_file_appears_on_finish_only() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("energy.csv");
        let mut file = AtomicFile::create(&path).unwrap();
        assert_eq!(file.path(), path);
        writeln!(file, "time,kinetic").unwrap();
        writeln!(file, "0e0,1e0").unwrap();
        assert!(!path.exists() && file.partial().exists());
        file.finish().unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "time,kinetic\n0e0,1e0\n"
        );
        assert_eq!(names(dir.path()), ["energy.csv"]);

        // Dropped unfinished: no file under either name.
        let other = dir.path().join("walls.csv");
        let mut file = AtomicFile::create(&other).unwrap();
        file.write_all(b"time\n").unwrap();
        drop(file);
        assert_eq!(names(dir.path()), ["energy.csv"]);
    }

    /// `clear_outputs` removes the named files, their temporaries and the series files
    /// with the prefix, and nothing else.
    #[test]
    fn clear_outputs_removes_only_the_named_outputs() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("frames")).unwrap();
        for f in [
            "a.csv",
            "a.csv.part",
            "keep.txt",
            "frames/frame_000001.vtu",
            "frames/other.vtu",
        ] {
            std::fs::write(d.join(f), "x").unwrap();
        }
        clear_outputs(
            d,
            &["a.csv", "missing.csv"],
            &[("frames", "frame_"), ("none", "x")],
        )
        .unwrap();
        assert_eq!(names(d), ["frames", "keep.txt"]);
        assert_eq!(names(&d.join("frames")), ["other.vtu"]);
    }
}
