//! The step's team: the pool's other workers kept awake between a run's parallel regions.
//!
//! A step opens a few parallel regions with short serial stretches between them (the
//! contact's spread, the contributions' forces, the driver's measures between steps). An
//! idle rayon worker spins for a few dozen rounds and then sleeps; waking it again is a
//! system call on the waking thread and a scheduling delay on the woken one, which on a
//! step of about a millisecond costs a noticeable share of what the second thread takes
//! over (docs/PERFORMANCE.md, "One persistent team"). A [`Team`] keeps every other worker
//! of the caller's pool in a loop that runs any job it can find ([`rayon::yield_now`]) and
//! otherwise waits on the CPU, so a region's jobs are taken at once. It changes who runs a
//! job and when, never what a job computes: results stay those of the thread count.
//!
//! A worker leaves the loop when the team is dropped, or on its own after
//! [`IDLE_LIMIT`] without a job (a driver writing output, say), so that a long pause
//! neither burns a core nor keeps it from other processes; [`Team::keep`] starts the loop
//! again for the next step. A worker that is itself in a step (of another simulation in
//! the same pool, waiting for one of its jobs) does not enter the loop: the loop would
//! hold that step's frame until the other team ended.

use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How long a worker of the team waits without a job before it leaves the loop (and may
/// sleep): a few steps of a small scene.
pub const IDLE_LIMIT: Duration = Duration::from_millis(5);

/// Idle rounds between two yields of the CPU to the operating system while a worker waits
/// in the loop (in between it only spins).
const SPINS_PER_YIELD: u32 = 64;

thread_local! {
    /// Whether this thread is inside a step ([`Team::stepping`]).
    static STEPPING: Cell<bool> = const { Cell::new(false) };
}

/// Marks the thread as inside a step until dropped ([`Team::stepping`]).
#[derive(Debug)]
pub struct Stepping {
    before: bool,
}

impl Drop for Stepping {
    fn drop(&mut self) {
        STEPPING.with(|s| s.set(self.before));
    }
}

/// The other workers of the caller's pool, kept awake while it lives (see the module's
/// documentation). Not cloned: each simulation holds its own.
#[derive(Debug)]
pub struct Team {
    shared: Option<Arc<Shared>>,
    /// How long a worker waits without a job before it leaves the loop.
    idle_limit: Duration,
}

impl Default for Team {
    fn default() -> Team {
        Team {
            shared: None,
            idle_limit: IDLE_LIMIT,
        }
    }
}

#[derive(Debug)]
struct Shared {
    /// Set when the team is dropped: every worker leaves its loop.
    done: AtomicBool,
    /// Workers in the loop now.
    awake: AtomicUsize,
}

impl Team {
    /// Makes sure the other workers of the caller's pool are in the team's loop: starts
    /// them if none is (the first call, or after they left on [`IDLE_LIMIT`]). Does
    /// nothing outside a rayon pool or in a pool of one thread.
    pub fn keep(&mut self) {
        let (Some(me), threads) = (rayon::current_thread_index(), rayon::current_num_threads())
        else {
            return;
        };
        if threads < 2 {
            return;
        }
        if let Some(shared) = &self.shared
            && shared.awake.load(Ordering::Acquire) > 0
        {
            return;
        }
        // The previous loops (if any) have all left or are leaving: start a new team, so
        // that a late leaver cannot count itself out of the new one.
        self.stop();
        let shared = Arc::new(Shared {
            done: AtomicBool::new(false),
            awake: AtomicUsize::new(threads - 1),
        });
        let (theirs, idle_limit) = (Arc::clone(&shared), self.idle_limit);
        rayon::spawn_broadcast(move |ctx| {
            if ctx.index() != me {
                wait_for_jobs(&theirs, idle_limit);
            }
        });
        self.shared = Some(shared);
    }

    /// Marks the calling thread as inside a step while the returned guard lives: a team's
    /// loop that reaches this thread (of another simulation) leaves at once.
    pub fn stepping() -> Stepping {
        Stepping {
            before: STEPPING.with(|s| s.replace(true)),
        }
    }

    /// Lets the workers leave their loop (they go back to rayon's own idling).
    pub fn stop(&mut self) {
        if let Some(shared) = self.shared.take() {
            shared.done.store(true, Ordering::Release);
        }
    }
}

impl Drop for Team {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A worker's loop: run any job of the pool, else spin (yielding the CPU now and then),
/// until the team is done or no job came for `idle_limit`.
fn wait_for_jobs(shared: &Shared, idle_limit: Duration) {
    if STEPPING.with(Cell::get) {
        shared.awake.fetch_sub(1, Ordering::AcqRel);
        return;
    }
    let mut idle_since: Option<Instant> = None;
    let mut rounds = 0u32;
    while !shared.done.load(Ordering::Acquire) {
        if let Some(rayon::Yield::Executed) = rayon::yield_now() {
            idle_since = None;
            continue;
        }
        rounds = rounds.wrapping_add(1);
        if !rounds.is_multiple_of(SPINS_PER_YIELD) {
            std::hint::spin_loop();
            continue;
        }
        std::thread::yield_now();
        let since = *idle_since.get_or_insert_with(Instant::now);
        if since.elapsed() >= idle_limit {
            break;
        }
    }
    shared.awake.fetch_sub(1, Ordering::AcqRel);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    /// Waits (up to 10 s) until no worker of `team` is in its loop.
    fn all_left(team: &Arc<Shared>) -> bool {
        let start = Instant::now();
        while team.awake.load(Ordering::Acquire) > 0 {
            if start.elapsed() > Duration::from_secs(10) {
                return false;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        true
    }

    /// Outside a pool, or in a pool of one thread, there is no one to keep awake.
    #[test]
    fn no_team_outside_a_pool_or_alone() {
        let mut team = Team::default();
        team.keep();
        assert!(team.shared.is_none());
        pool(1).install(|| team.keep());
        assert!(team.shared.is_none());
    }

    /// The other worker joins the loop, takes the jobs of parallel regions and of a
    /// blocking broadcast (which needs every worker) while in it, and leaves it when the
    /// team is dropped.
    #[test]
    fn the_other_worker_runs_jobs_in_the_loop_and_leaves_on_drop() {
        pool(2).install(|| {
            // An idle limit the test never reaches: only the drop can end the loop.
            let mut team = Team {
                shared: None,
                idle_limit: Duration::from_secs(3600),
            };
            team.keep();
            let shared = Arc::clone(team.shared.as_ref().expect("a team in a pool of two"));
            std::thread::sleep(2 * IDLE_LIMIT);
            assert_eq!(
                shared.awake.load(Ordering::Acquire),
                1,
                "the worker left early"
            );
            let sum: u64 = (0..100_000u64).into_par_iter().sum();
            assert_eq!(sum, 100_000 * 99_999 / 2);
            let workers = rayon::broadcast(|ctx| ctx.index());
            assert_eq!(workers, vec![0, 1]);
            // A second call keeps the same team while its worker is in the loop.
            team.keep();
            assert!(Arc::ptr_eq(&shared, team.shared.as_ref().unwrap()));
            drop(team);
            assert!(
                all_left(&shared),
                "the worker stayed in the loop after the drop"
            );
        });
    }

    /// A worker with no job for the idle limit leaves the loop on its own, and the next
    /// `keep` starts a new team.
    #[test]
    fn an_idle_worker_leaves_and_keep_starts_it_again() {
        pool(2).install(|| {
            let mut team = Team::default();
            team.keep();
            let first = Arc::clone(team.shared.as_ref().unwrap());
            std::thread::sleep(IDLE_LIMIT);
            assert!(all_left(&first), "the idle worker stayed in the loop");
            assert!(!first.done.load(Ordering::Acquire));
            team.keep();
            let second = team.shared.as_ref().unwrap();
            assert!(!Arc::ptr_eq(&first, second));
            assert!(
                first.done.load(Ordering::Acquire),
                "the old team was not stopped"
            );
        });
    }

    /// A worker inside a step (of another simulation sharing the pool) does not enter the
    /// loop, which would hold its step until the team ended.
    #[test]
    fn a_worker_inside_a_step_does_not_enter_the_loop() {
        pool(2).install(|| {
            let (tx, rx) = std::sync::mpsc::channel();
            let released = Arc::new(AtomicBool::new(false));
            let wait = Arc::clone(&released);
            // The other worker starts a "step" and waits in it for work of the pool.
            rayon::spawn(move || {
                let _stepping = Team::stepping();
                tx.send(()).unwrap();
                while !wait.load(Ordering::Acquire) {
                    rayon::yield_now();
                }
            });
            rx.recv().unwrap();
            let mut team = Team {
                shared: None,
                idle_limit: Duration::from_secs(3600),
            };
            team.keep();
            let shared = Arc::clone(team.shared.as_ref().unwrap());
            assert!(all_left(&shared), "a worker inside a step entered the loop");
            released.store(true, Ordering::Release);
        });
        assert!(!STEPPING.with(Cell::get));
    }
}
