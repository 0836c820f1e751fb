//! `remove_unfinished` acts on every temporary of the process, so its test runs in a
//! process of its own (this file holds one test).

use fdem_core::fs::{AtomicFile, remove_unfinished, write_atomically};
use std::io::Write;

fn names(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    names
}

/// An exit that runs no destructors removes the temporaries still being written through
/// `remove_unfinished`, and only those; the writer's own end then fails cleanly.
#[test]
fn unfinished_temporaries_are_removed_on_request() {
    let dir = tempfile::tempdir().unwrap();
    write_atomically(&dir.path().join("done.csv"), "x").unwrap();
    let mut open = AtomicFile::create(&dir.path().join("open.csv")).unwrap();
    writeln!(open, "time").unwrap();
    assert_eq!(names(dir.path()), ["done.csv", "open.csv.part"]);
    assert_eq!(remove_unfinished(), 1);
    assert_eq!(names(dir.path()), ["done.csv"]);
    assert!(open.finish().is_err());
    assert_eq!(names(dir.path()), ["done.csv"]);
    assert_eq!(remove_unfinished(), 0);
}
