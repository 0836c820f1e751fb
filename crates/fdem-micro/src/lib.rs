//! # fdem-micro (not yet implemented)
//!
//! Will own the contact-force micro-analysis of MODEL.md section 9: DBSCAN clustering of
//! node-level contact forces per particle, pairing of clusters into particle contacts,
//! contact statistics and their validation against per body-pair ground truth. It reads
//! snapshots, never solver state. This crate is an empty placeholder until the
//! micro-analysis issue fills it.
#![warn(missing_docs)]
