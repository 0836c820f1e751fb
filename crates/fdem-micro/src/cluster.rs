//! Clustering node contacts into particle contacts (docs/MODEL.md section 9).
//!
//! 1. **Nodes.** Rows whose normal force exceeds [`ClusterParams::min_normal_force`]
//!    (default: any non-zero force). Rows of the same node, body and counterpart are
//!    summed (a code that spreads reactions onto face nodes may list a node several times).
//! 2. **Per particle DBSCAN.** The nodes of one body are clustered separately for each
//!    counterpart they record (`other_body`, `other_wall`, or unknown when both are empty),
//!    with neighbourhood radius `eps` and `min_points` ([`crate::dbscan()`]). Default `eps`:
//!    [`ClusterParams::eps_factor`] (1.5) times the body's node spacing, the median
//!    distance from a force-carrying node to its nearest neighbour in the same cloud
//!    (distances beyond [`LOCAL_SPACING_RANGE`] times the snapshot's median left out, the
//!    result kept within that factor of it); a body with fewer than
//!    [`MIN_LOCAL_SAMPLES`] such distances uses the snapshot's median.
//!    On a triangulated surface adjacent nodes are one edge apart, so 1.5 spacings join
//!    the nodes of one patch (the surface edges of fdem's spheres are within about 10 %
//!    of their mean) but not nodes two edges apart.
//! 3. **Pairing.**
//!    - *Recorded body counterpart* (fdem's snapshots): a cluster of A's nodes pressed
//!      into B's faces is already (part of) a contact between A and B. Node-to-face
//!      contact is symmetric, so the same contact may also show B's nodes pressed into
//!      A's faces: clusters on the two sides of the same body pair whose force-weighted
//!      positions are within [`ClusterParams::pair_distance_factor`] x eps (default 2) of
//!      each other merge into one contact (transitively). No force test: each side holds
//!      a share of the contact force and both push the bodies apart, so the force on the
//!      lower body is the sum of its side minus the sum of the other side, exactly
//!      fdem's per-pair convention.
//!    - *Wall counterpart*: each cluster is a boundary contact with that wall.
//!    - *Unknown counterpart* (codes that put action and reaction on both bodies' nodes):
//!      clusters on two different bodies pair when their force-weighted positions are
//!      within pair_distance_factor x eps and their total forces are equal and opposite
//!      within [`ClusterParams::force_tolerance`] (`|F_a + F_b| <= tol max(|F_a|, |F_b|)`,
//!      default 0.1); candidates are matched greedily, best first (distance and force
//!      mismatch, each relative to its tolerance). Unpaired clusters are boundary contacts
//!      with an unknown counterpart (walls, membrane, platens of such codes).
//!    - Contacts that involve a body listed in [`ClusterParams::boundary_bodies`]
//!      (a meshed membrane or platen) are boundary contacts too.

use crate::MicroError;
use crate::dbscan::{dbscan, nearest_neighbour_distances, tree_of};
use crate::snapshot::{Counterpart, Snapshot};
use crate::vec3::{add, distance, norm, scale};
use fdem_core::statistics::median;
use kiddo::SquaredEuclidean;
use serde::Serialize;
use std::collections::BTreeSet;

/// A body needs at least this many nearest-neighbour distances of its own for a local
/// node spacing; with fewer it uses the snapshot's median.
pub const MIN_LOCAL_SAMPLES: usize = 4;

/// A body's local spacing is kept within this factor of the snapshot's median spacing,
/// and only its nearest-neighbour distances up to this factor times the median count
/// (longer ones are gaps between separate contact patches, not mesh edges). Mesh sizes
/// that differ by more than this factor from the median need an explicit eps.
pub const LOCAL_SPACING_RANGE: f64 = 2.0;

/// Parameters of the clustering and pairing. The defaults are documented on each field
/// and in docs/MICRO.md.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClusterParams {
    /// Neighbourhood radius of DBSCAN (m). `None` (default): `eps_factor` times the
    /// body's node spacing (see the module docs).
    pub eps: Option<f64>,
    /// Multiple of the node spacing used as eps when `eps` is `None`. Default 1.5.
    pub eps_factor: f64,
    /// DBSCAN's minimum neighbourhood size (the point itself included). Default 1: every
    /// node is a core point and an isolated node is a contact of its own.
    pub min_points: usize,
    /// Two clusters are at the same place when their force-weighted positions are at most
    /// this many eps apart (the larger eps of the two bodies). Default 2.
    pub pair_distance_factor: f64,
    /// Relative tolerance on `|F_a + F_b|` for pairing clusters whose counterpart is not
    /// recorded. Default 0.1.
    pub force_tolerance: f64,
    /// Rows whose normal force magnitude is at most this (N) are ignored. Default 0: every
    /// row with a non-zero normal force counts.
    pub min_normal_force: f64,
    /// Bodies that are boundaries (a meshed membrane or platen), not particles: their
    /// contacts are boundary contacts and they do not count as particles.
    pub boundary_bodies: Vec<u32>,
}

impl Default for ClusterParams {
    fn default() -> Self {
        ClusterParams {
            eps: None,
            eps_factor: 1.5,
            min_points: 1,
            pair_distance_factor: 2.0,
            force_tolerance: 0.1,
            min_normal_force: 0.0,
            boundary_bodies: Vec::new(),
        }
    }
}

impl ClusterParams {
    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), MicroError> {
        let check = |name, value: f64, ok: bool, requirement| {
            if ok {
                Ok(())
            } else {
                Err(MicroError::InvalidParameter {
                    name,
                    value,
                    requirement,
                })
            }
        };
        if let Some(eps) = self.eps {
            check(
                "eps",
                eps,
                eps.is_finite() && eps > 0.0,
                "a positive finite length (m)",
            )?;
        }
        let f = self.eps_factor;
        check(
            "eps_factor",
            f,
            f.is_finite() && f > 0.0,
            "a positive finite number",
        )?;
        check(
            "min_points",
            self.min_points as f64,
            self.min_points >= 1,
            "at least 1",
        )?;
        let f = self.pair_distance_factor;
        check(
            "pair_distance_factor",
            f,
            f.is_finite() && f > 0.0,
            "a positive finite number",
        )?;
        let f = self.force_tolerance;
        check(
            "force_tolerance",
            f,
            f.is_finite() && f >= 0.0,
            "a finite number >= 0",
        )?;
        let f = self.min_normal_force;
        check(
            "min_normal_force",
            f,
            f.is_finite() && f >= 0.0,
            "a finite force >= 0 (N)",
        )
    }
}

/// Whether a contact is between two particles or involves a boundary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactKind {
    /// Between two particles: counted in the statistics.
    Particle,
    /// With a wall, a boundary body or an unknown counterpart.
    Boundary,
}

/// One particle-level contact.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Contact {
    /// Particle or boundary contact.
    pub kind: ContactKind,
    /// The body the forces act on: the lower id of a body pair, the particle otherwise.
    pub body: u32,
    /// The other body (higher id), a wall, or unknown (an unpaired cluster).
    pub other: Counterpart,
    /// Contact position: the node positions weighted by their normal force (m).
    pub position: [f64; 3],
    /// Normal force on `body` (N): the vector sum over the contact's nodes.
    pub normal_force: [f64; 3],
    /// Tangential force on `body` (N).
    pub tangential_force: [f64; 3],
    /// Number of node entries in the contact (both sides).
    pub nodes: usize,
    /// Number of per-particle DBSCAN clusters merged into it.
    pub clusters: usize,
}

impl Contact {
    /// Magnitude of the normal force (N).
    pub fn normal_magnitude(&self) -> f64 {
        norm(self.normal_force)
    }

    /// Magnitude of the tangential force (N).
    pub fn tangential_magnitude(&self) -> f64 {
        norm(self.tangential_force)
    }
}

/// The result of [`cluster`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Clustering {
    /// Time of the snapshot (s).
    pub time: f64,
    /// All contacts, sorted by kind, body and counterpart.
    pub contacts: Vec<Contact>,
    /// Rows of the snapshot.
    pub rows: usize,
    /// Rows ignored because their node's normal force (summed over its rows) is at or
    /// below the threshold.
    pub ignored_rows: usize,
    /// Node entries clustered (rows after summing duplicates).
    pub nodes: usize,
    /// Nodes DBSCAN left as noise (only with `min_points > 1`); their forces are lost.
    pub noise_nodes: usize,
    /// Per-particle clusters found.
    pub clusters: usize,
    /// Clusters with an unknown counterpart that found no partner (boundary contacts).
    pub unpaired_clusters: usize,
    /// Median nearest-neighbour spacing of the force-carrying nodes over the snapshot (m);
    /// `None` when no cloud has two nodes.
    pub spacing: Option<f64>,
    /// Smallest and largest eps used (m); infinite when no spacing could be measured.
    pub eps_range: Option<[f64; 2]>,
    /// Distinct particles (bodies not listed as boundaries) with a force-carrying node.
    pub particles_seen: usize,
}

/// One force-carrying node entry.
#[derive(Clone, Copy, Debug)]
struct Entry {
    body: u32,
    key: Counterpart,
    node: u64,
    position: [f64; 3],
    normal: [f64; 3],
    tangential: [f64; 3],
    /// Rows summed into this entry.
    rows: usize,
}

/// One per-particle cluster.
#[derive(Clone, Copy, Debug)]
struct Cluster {
    body: u32,
    key: Counterpart,
    eps: f64,
    /// Sum of `|F_n| x` and of `|F_n|` over the nodes.
    weighted_position: [f64; 3],
    weight: f64,
    normal: [f64; 3],
    tangential: [f64; 3],
    nodes: usize,
}

impl Cluster {
    fn centroid(&self) -> [f64; 3] {
        scale(self.weighted_position, 1.0 / self.weight)
    }

    fn total(&self) -> [f64; 3] {
        add(self.normal, self.tangential)
    }
}

/// Minimal union-find over cluster indices.
struct UnionFind(Vec<usize>);

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind((0..n).collect())
    }
    fn find(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }
    fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        self.0[a.max(b)] = a.min(b);
    }
}

/// Accumulates clusters into one contact whose forces act on `body`.
struct Builder {
    contact: Contact,
    weighted_position: [f64; 3],
    weight: f64,
}

impl Builder {
    fn new(kind: ContactKind, body: u32, other: Counterpart) -> Self {
        Builder {
            contact: Contact {
                kind,
                body,
                other,
                position: [0.0; 3],
                normal_force: [0.0; 3],
                tangential_force: [0.0; 3],
                nodes: 0,
                clusters: 0,
            },
            weighted_position: [0.0; 3],
            weight: 0.0,
        }
    }

    /// Adds a cluster whose forces act on `body` (`sign` 1) or on the other body (`sign`
    /// -1, action and reaction) scaled by `share`.
    fn add(&mut self, c: &Cluster, sign: f64, share: f64) {
        let k = sign * share;
        let t = &mut self.contact;
        t.normal_force = add(t.normal_force, scale(c.normal, k));
        t.tangential_force = add(t.tangential_force, scale(c.tangential, k));
        t.nodes += c.nodes;
        t.clusters += 1;
        self.weighted_position = add(self.weighted_position, c.weighted_position);
        self.weight += c.weight;
    }

    fn finish(mut self) -> Contact {
        self.contact.position = scale(self.weighted_position, 1.0 / self.weight);
        self.contact
    }
}

/// Clusters the node contacts of a snapshot into particle contacts (see the module docs).
pub fn cluster(snapshot: &Snapshot, params: &ClusterParams) -> Result<Clustering, MicroError> {
    params.validate()?;
    let boundary: BTreeSet<u32> = params.boundary_bodies.iter().copied().collect();
    check_rows(snapshot)?;

    // 1. Node entries sorted by body, counterpart, node; rows of one node summed; then
    //    the entries without a normal force (above the threshold) left out.
    let (entries, ignored_rows) = node_entries(snapshot, params.min_normal_force);
    let particles_seen = particles_seen(&entries, &boundary);
    let groups = groups(&entries);

    // 2. Node spacing: nearest-neighbour distances inside each group, per body and overall.
    let (samples, spacing) = spacing_samples(&entries, &groups);
    let eps = EpsTable::new(params, spacing, &samples);

    // 3. DBSCAN per group.
    let (clusters, noise_nodes, eps_range) = cluster_groups(&entries, &groups, &eps, params);

    // 4. Contacts: walls, recorded body counterparts, unknown counterparts.
    let mut contacts: Vec<Contact> = Vec::new();
    wall_contacts(&clusters, &mut contacts);
    recorded_pair_contacts(&clusters, params, &boundary, &mut contacts);
    let unpaired_clusters = unknown_contacts(&clusters, params, &boundary, &mut contacts);
    contacts.sort_by(|a, b| {
        (a.kind, a.body, a.other)
            .cmp(&(b.kind, b.body, b.other))
            .then(a.position[0].total_cmp(&b.position[0]))
            .then(a.position[1].total_cmp(&b.position[1]))
            .then(a.position[2].total_cmp(&b.position[2]))
    });
    Ok(Clustering {
        time: snapshot.time,
        contacts,
        rows: snapshot.rows.len(),
        ignored_rows,
        nodes: entries.len(),
        noise_nodes,
        clusters: clusters.len(),
        unpaired_clusters,
        spacing,
        eps_range,
        particles_seen,
    })
}

/// Refuses a snapshot with a non-finite position or force component.
fn check_rows(snapshot: &Snapshot) -> Result<(), MicroError> {
    for (i, r) in snapshot.rows.iter().enumerate() {
        let finite = r
            .position
            .iter()
            .chain(&r.normal_force)
            .chain(&r.tangential_force)
            .all(|v| v.is_finite());
        if !finite {
            return Err(MicroError::InvalidRow {
                row: i,
                node: r.node,
                body: r.body,
                message: "a position or force component is not finite".to_string(),
            });
        }
    }
    Ok(())
}

/// The node entries sorted by body, counterpart and node, the rows of one node summed,
/// those whose normal force is at most `min_normal_force` left out; and the number of rows
/// left out.
fn node_entries(snapshot: &Snapshot, min_normal_force: f64) -> (Vec<Entry>, usize) {
    let mut entries: Vec<Entry> = snapshot
        .rows
        .iter()
        .map(|r| Entry {
            body: r.body,
            key: r.counterpart,
            node: r.node,
            position: r.position,
            normal: r.normal_force,
            tangential: r.tangential_force,
            rows: 1,
        })
        .collect();
    entries.sort_by_key(|e| (e.body, e.key, e.node));
    entries.dedup_by(|later, kept| {
        let same = (later.body, later.key, later.node) == (kept.body, kept.key, kept.node);
        if same {
            kept.normal = add(kept.normal, later.normal);
            kept.tangential = add(kept.tangential, later.tangential);
            kept.rows += later.rows;
        }
        same
    });
    let mut ignored_rows = 0;
    entries.retain(|e| {
        let keep = norm(e.normal) > min_normal_force;
        if !keep {
            ignored_rows += e.rows;
        }
        keep
    });
    (entries, ignored_rows)
}

/// Distinct particles (bodies not in `boundary`) among the entries' bodies and recorded
/// body counterparts.
fn particles_seen(entries: &[Entry], boundary: &BTreeSet<u32>) -> usize {
    let mut bodies: Vec<u32> = entries
        .iter()
        .map(|e| e.body)
        .chain(entries.iter().filter_map(|e| match e.key {
            Counterpart::Body(b) => Some(b),
            _ => None,
        }))
        .filter(|b| !boundary.contains(b))
        .collect();
    bodies.sort_unstable();
    bodies.dedup();
    bodies.len()
}

/// Groups of the sorted entries: runs of equal (body, counterpart).
fn groups(entries: &[Entry]) -> Vec<std::ops::Range<usize>> {
    let mut groups: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start = 0;
    for i in 1..=entries.len() {
        if i == entries.len()
            || (entries[i].body, entries[i].key) != (entries[start].body, entries[start].key)
        {
            if i > start {
                groups.push(start..i);
            }
            start = i;
        }
    }
    groups
}

/// The non-zero nearest-neighbour distances inside each group with their body (in body
/// order, as the groups are), and their median over the snapshot.
fn spacing_samples(
    entries: &[Entry],
    groups: &[std::ops::Range<usize>],
) -> (Vec<(u32, f64)>, Option<f64>) {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut samples: Vec<(u32, f64)> = Vec::new();
    for g in groups {
        positions.clear();
        positions.extend(entries[g.clone()].iter().map(|e| e.position));
        let body = entries[g.start].body;
        samples.extend(
            nearest_neighbour_distances(&positions)
                .into_iter()
                .filter(|d| *d > 0.0)
                .map(|d| (body, d)),
        );
    }
    let mut all: Vec<f64> = samples.iter().map(|s| s.1).collect();
    let spacing = median(&mut all);
    (samples, spacing)
}

/// The DBSCAN radius of each body: from its local spacing where it has enough samples of
/// its own, else the global one.
struct EpsTable {
    /// `eps` if given, else `eps_factor` times the snapshot's spacing (infinite without).
    global: f64,
    /// Body -> eps, in body order.
    per_body: Vec<(u32, f64)>,
}

impl EpsTable {
    /// The radii for `params`, the snapshot's `spacing` and its `samples` (sorted by body).
    fn new(params: &ClusterParams, spacing: Option<f64>, samples: &[(u32, f64)]) -> EpsTable {
        let global_eps = params
            .eps
            .unwrap_or_else(|| spacing.map_or(f64::INFINITY, |s| params.eps_factor * s));
        let mut body_eps: Vec<(u32, f64)> = Vec::new();
        if let (None, Some(global)) = (params.eps, spacing) {
            let (lo, hi) = (global / LOCAL_SPACING_RANGE, global * LOCAL_SPACING_RANGE);
            let mut i = 0;
            let mut local = Vec::new();
            while i < samples.len() {
                let body = samples[i].0;
                local.clear();
                while i < samples.len() && samples[i].0 == body {
                    // Longer distances join separate patches, not neighbouring nodes.
                    if samples[i].1 <= hi {
                        local.push(samples[i].1);
                    }
                    i += 1;
                }
                if local.len() >= MIN_LOCAL_SAMPLES
                    && let Some(m) = median(&mut local)
                {
                    body_eps.push((body, params.eps_factor * m.clamp(lo, hi)));
                }
            }
        }
        EpsTable {
            global: global_eps,
            per_body: body_eps,
        }
    }

    /// The radius of `body` (m).
    fn of(&self, body: u32) -> f64 {
        self.per_body
            .binary_search_by_key(&body, |e| e.0)
            .map_or(self.global, |i| self.per_body[i].1)
    }
}

/// DBSCAN over each group: the clusters in group order, the nodes left as noise, and the
/// smallest and largest eps used.
fn cluster_groups(
    entries: &[Entry],
    groups: &[std::ops::Range<usize>],
    eps: &EpsTable,
    params: &ClusterParams,
) -> (Vec<Cluster>, usize, Option<[f64; 2]>) {
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut clusters: Vec<Cluster> = Vec::new();
    let mut noise_nodes = 0;
    let mut eps_range: Option<[f64; 2]> = None;
    for g in groups {
        let (body, key) = (entries[g.start].body, entries[g.start].key);
        let eps = eps.of(body);
        eps_range = Some(eps_range.map_or([eps, eps], |[lo, hi]| [lo.min(eps), hi.max(eps)]));
        positions.clear();
        positions.extend(entries[g.clone()].iter().map(|e| e.position));
        let labels = dbscan(&positions, eps, params.min_points);
        let first = clusters.len();
        let count = labels
            .iter()
            .flatten()
            .map(|&l| l as usize + 1)
            .max()
            .unwrap_or(0);
        clusters.extend((0..count).map(|_| Cluster {
            body,
            key,
            eps,
            weighted_position: [0.0; 3],
            weight: 0.0,
            normal: [0.0; 3],
            tangential: [0.0; 3],
            nodes: 0,
        }));
        for (e, label) in entries[g.clone()].iter().zip(&labels) {
            let Some(l) = label else {
                noise_nodes += 1;
                continue;
            };
            let c = &mut clusters[first + *l as usize];
            let w = norm(e.normal);
            c.weighted_position = add(c.weighted_position, scale(e.position, w));
            c.weight += w;
            c.normal = add(c.normal, e.normal);
            c.tangential = add(c.tangential, e.tangential);
            c.nodes += 1;
        }
    }
    (clusters, noise_nodes, eps_range)
}

/// Particle contact, or boundary contact when body `a` or `b` is a boundary.
fn kind_of(boundary: &BTreeSet<u32>, a: u32, b: Option<u32>) -> ContactKind {
    if boundary.contains(&a) || b.is_some_and(|b| boundary.contains(&b)) {
        ContactKind::Boundary
    } else {
        ContactKind::Particle
    }
}

/// 4a. Each cluster against a wall is a boundary contact with that wall.
fn wall_contacts(clusters: &[Cluster], contacts: &mut Vec<Contact>) {
    for c in clusters
        .iter()
        .filter(|c| matches!(c.key, Counterpart::Wall(_)))
    {
        let mut b = Builder::new(ContactKind::Boundary, c.body, c.key);
        b.add(c, 1.0, 1.0);
        contacts.push(b.finish());
    }
}

/// 4b. Recorded body counterparts: the clusters of each body pair, on both sides, merged
/// (transitively) where their positions are within pair_distance_factor x eps.
fn recorded_pair_contacts(
    clusters: &[Cluster],
    params: &ClusterParams,
    boundary: &BTreeSet<u32>,
    contacts: &mut Vec<Contact>,
) {
    let mut by_pair: Vec<(u32, u32, usize)> = clusters
        .iter()
        .enumerate()
        .filter_map(|(i, c)| match c.key {
            Counterpart::Body(o) => Some((c.body.min(o), c.body.max(o), i)),
            _ => None,
        })
        .collect();
    by_pair.sort_unstable();
    let mut start = 0;
    while start < by_pair.len() {
        let (lo, hi) = (by_pair[start].0, by_pair[start].1);
        let mut end = start;
        while end < by_pair.len() && (by_pair[end].0, by_pair[end].1) == (lo, hi) {
            end += 1;
        }
        let members: Vec<usize> = by_pair[start..end].iter().map(|m| m.2).collect();
        let mut sets = UnionFind::new(members.len());
        for a in 0..members.len() {
            for b in 0..a {
                let (ca, cb) = (&clusters[members[a]], &clusters[members[b]]);
                if ca.body == cb.body {
                    continue;
                }
                let limit = params.pair_distance_factor * ca.eps.max(cb.eps);
                if distance(ca.centroid(), cb.centroid()) <= limit {
                    sets.union(a, b);
                }
            }
        }
        let mut roots: Vec<(usize, usize)> =
            (0..members.len()).map(|a| (sets.find(a), a)).collect();
        roots.sort_unstable();
        let mut r = 0;
        while r < roots.len() {
            let mut b = Builder::new(kind_of(boundary, lo, Some(hi)), lo, Counterpart::Body(hi));
            let root = roots[r].0;
            while r < roots.len() && roots[r].0 == root {
                let c = &clusters[members[roots[r].1]];
                b.add(c, if c.body == lo { 1.0 } else { -1.0 }, 1.0);
                r += 1;
            }
            contacts.push(b.finish());
        }
        start = end;
    }
}

/// 4c. Unknown counterparts: geometric pairing of action and reaction ([`pair_unknown`]);
/// an unpaired cluster is a boundary contact with an unknown counterpart. Returns the
/// number of unpaired clusters.
fn unknown_contacts(
    clusters: &[Cluster],
    params: &ClusterParams,
    boundary: &BTreeSet<u32>,
    contacts: &mut Vec<Contact>,
) -> usize {
    let unknown: Vec<usize> = (0..clusters.len())
        .filter(|&i| clusters[i].key == Counterpart::Unknown)
        .collect();
    let partner = pair_unknown(clusters, &unknown, params);
    let mut unpaired_clusters = 0;
    for (k, &i) in unknown.iter().enumerate() {
        let c = &clusters[i];
        match partner[k] {
            Some(m) => {
                let o = &clusters[unknown[m]];
                if c.body > o.body {
                    continue; // the pair is built once, from its lower body
                }
                let mut b = Builder::new(
                    kind_of(boundary, c.body, Some(o.body)),
                    c.body,
                    Counterpart::Body(o.body),
                );
                // Each side holds the whole contact force: average action and -reaction.
                b.add(c, 1.0, 0.5);
                b.add(o, -1.0, 0.5);
                contacts.push(b.finish());
            }
            None => {
                unpaired_clusters += 1;
                let mut b = Builder::new(ContactKind::Boundary, c.body, Counterpart::Unknown);
                b.add(c, 1.0, 1.0);
                contacts.push(b.finish());
            }
        }
    }
    unpaired_clusters
}

/// Greedy best-first matching of unknown-counterpart clusters on different bodies
/// (positions within pair_distance_factor x eps, forces equal and opposite within the
/// tolerance). Returns, for each entry of `unknown`, the index (into `unknown`) of its
/// partner.
fn pair_unknown(
    clusters: &[Cluster],
    unknown: &[usize],
    params: &ClusterParams,
) -> Vec<Option<usize>> {
    let n = unknown.len();
    let mut partner = vec![None; n];
    if n < 2 {
        return partner;
    }
    let centroids: Vec<[f64; 3]> = unknown.iter().map(|&i| clusters[i].centroid()).collect();
    let max_eps = unknown
        .iter()
        .map(|&i| clusters[i].eps)
        .fold(0.0f64, f64::max);
    let radius = params.pair_distance_factor * max_eps;
    let mut edges: Vec<(f64, usize, usize)> = Vec::new();
    let consider = |a: usize, b: usize, edges: &mut Vec<(f64, usize, usize)>| {
        let (ca, cb) = (&clusters[unknown[a]], &clusters[unknown[b]]);
        if ca.body == cb.body {
            return;
        }
        let limit = params.pair_distance_factor * ca.eps.max(cb.eps);
        let d = distance(centroids[a], centroids[b]);
        let (fa, fb) = (ca.total(), cb.total());
        let scale_force = norm(fa).max(norm(fb));
        let mismatch = if scale_force > 0.0 {
            norm(add(fa, fb)) / scale_force
        } else {
            0.0
        };
        if d <= limit && mismatch <= params.force_tolerance {
            let distance_score = if limit.is_finite() { d / limit } else { 0.0 };
            let force_score = if params.force_tolerance > 0.0 {
                mismatch / params.force_tolerance
            } else {
                0.0
            };
            edges.push((distance_score + force_score, a.min(b), a.max(b)));
        }
    };
    let tree = if radius.is_finite() {
        tree_of(&centroids)
    } else {
        None
    };
    if let Some(tree) = tree {
        for (a, p) in centroids.iter().enumerate() {
            for r in tree
                .query(p)
                .within::<SquaredEuclidean<f64>>(radius * radius)
                .unsorted()
                .execute()
            {
                let b = r.item as usize;
                if b > a {
                    consider(a, b, &mut edges);
                }
            }
        }
    } else {
        for a in 0..n {
            for b in a + 1..n {
                consider(a, b, &mut edges);
            }
        }
    }
    edges.sort_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
    for (_, a, b) in edges {
        if partner[a].is_none() && partner[b].is_none() {
            partner[a] = Some(b);
            partner[b] = Some(a);
        }
    }
    partner
}

/// Header of the per-contact CSV written by [`write_contacts`].
pub const CONTACTS_HEADER: &str =
    "time,kind,body,other_body,other_wall,x,y,z,fnx,fny,fnz,ftx,fty,ftz,fn,ft,nodes,clusters";

/// Writes every contact of `clustering` as CSV ([`CONTACTS_HEADER`]; forces on `body`, N;
/// position in m; both counterpart columns empty for an unknown counterpart), atomically.
pub fn write_contacts(path: &std::path::Path, clustering: &Clustering) -> Result<(), MicroError> {
    use fdem_core::snapshot::write_vector_columns;
    use std::fmt::Write as _;
    let mut text = String::from(CONTACTS_HEADER);
    text.push('\n');
    let t = clustering.time;
    for c in &clustering.contacts {
        let kind = match c.kind {
            ContactKind::Particle => "particle",
            ContactKind::Boundary => "boundary",
        };
        let _ = write!(text, "{t:e},{kind},{},", c.body);
        // Counterpart and vector columns as in the snapshot format.
        c.other.write_columns(&mut text);
        for v in [c.position, c.normal_force, c.tangential_force] {
            write_vector_columns(&mut text, v);
        }
        let _ = writeln!(
            text,
            ",{:e},{:e},{},{}",
            c.normal_magnitude(),
            c.tangential_magnitude(),
            c.nodes,
            c.clusters
        );
    }
    crate::snapshot::write_atomically(path, text.as_bytes())
}
