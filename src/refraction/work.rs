//! Work counters of the exact method, in test builds only (nothing of this is compiled into the
//! renderer): Newton solves, their evaluations of `grad L` and `Hess L`, path checks and the
//! visibility walks' surface evaluations, each by what asked for it. Per thread, summed over
//! rayon's threads by [`take`]. Read by the tuning aid `frame::wake_tuning`.

use std::cell::{Cell, RefCell};

/// What a solve or a path check is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The first solve from a linear image of a vertex.
    LinearImage = 0,
    /// A retry of a failed one from a seed around it.
    Retry = 1,
    /// A subdivision's edge midpoint.
    Midpoint = 2,
    /// Anything else (the linear search's crest checks, tests).
    Other = 3,
}

pub const SOURCES: [&str; 4] = ["linear image", "retry", "midpoint", "other"];

/// Counts, per [`Source`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Work {
    pub solves: [u64; 4],
    pub converged: [u64; 4],
    /// Evaluations of `grad L` and `Hess L` (each one height, gradient and Hessian of the surface).
    pub evaluations: [u64; 4],
    pub path_checks: [u64; 4],
    /// Height-and-gradient evaluations of the visibility walks.
    pub walk_evaluations: [u64; 4],
    /// Converged solves by their Newton iterations (the last bucket: that many or more).
    pub converged_iterations: [[u64; 51]; 4],
    /// Solves by their evaluations, converged and failed (the last bucket: that many or more).
    pub converged_evaluations: [[u64; 201]; 4],
    pub failed_evaluations: [[u64; 201]; 4],
    /// Converged solves by the most line-search trials one iteration needed (1: full steps only).
    pub converged_trials: [[u64; 13]; 4],
    /// Failed solves: the evaluations they would have made had the line search given up after
    /// `n` trials (index n), summed.
    pub failed_evaluations_capped: [[u64; 13]; 4],
    /// Subdivision: edges tested (a midpoint solved or not), and edges split.
    pub edge_tests: u64,
    pub edge_splits: u64,
}

impl Default for Work {
    fn default() -> Self {
        Work {
            solves: [0; 4],
            converged: [0; 4],
            evaluations: [0; 4],
            path_checks: [0; 4],
            walk_evaluations: [0; 4],
            converged_iterations: [[0; 51]; 4],
            converged_evaluations: [[0; 201]; 4],
            failed_evaluations: [[0; 201]; 4],
            converged_trials: [[0; 13]; 4],
            failed_evaluations_capped: [[0; 13]; 4],
            edge_tests: 0,
            edge_splits: 0,
        }
    }
}

impl Work {
    /// Every counter of `self` and `other`, in pairs.
    fn pairs<'a>(&'a mut self, other: &'a Work) -> impl Iterator<Item = (&'a mut u64, &'a u64)> {
        let per_source = |mine: &'a mut [u64], theirs: &'a [u64]| mine.iter_mut().zip(theirs);
        per_source(&mut self.solves, &other.solves)
            .chain(per_source(&mut self.converged, &other.converged))
            .chain(per_source(&mut self.evaluations, &other.evaluations))
            .chain(per_source(&mut self.path_checks, &other.path_checks))
            .chain(per_source(
                &mut self.walk_evaluations,
                &other.walk_evaluations,
            ))
            .chain(per_source(
                self.converged_iterations.as_flattened_mut(),
                other.converged_iterations.as_flattened(),
            ))
            .chain(per_source(
                self.converged_evaluations.as_flattened_mut(),
                other.converged_evaluations.as_flattened(),
            ))
            .chain(per_source(
                self.failed_evaluations.as_flattened_mut(),
                other.failed_evaluations.as_flattened(),
            ))
            .chain(per_source(
                self.converged_trials.as_flattened_mut(),
                other.converged_trials.as_flattened(),
            ))
            .chain(per_source(
                self.failed_evaluations_capped.as_flattened_mut(),
                other.failed_evaluations_capped.as_flattened(),
            ))
            .chain([
                (&mut self.edge_tests, &other.edge_tests),
                (&mut self.edge_splits, &other.edge_splits),
            ])
    }

    fn add(&mut self, other: &Work) {
        self.pairs(other).for_each(|(mine, theirs)| *mine += theirs);
    }

    /// The counts of `self` not in `part` (counted as part of them).
    pub fn less(mut self, part: &Work) -> Work {
        self.pairs(part).for_each(|(mine, theirs)| *mine -= theirs);
        self
    }
}

thread_local! {
    static SOURCE: Cell<Source> = const { Cell::new(Source::Other) };
    static WORK: RefCell<Work> = RefCell::new(Work::default());
}

/// Sets the source of what this thread counts until the guard drops.
pub struct SourceGuard(Source);

impl Drop for SourceGuard {
    fn drop(&mut self) {
        SOURCE.with(|s| s.set(self.0));
    }
}

pub fn source(source: Source) -> SourceGuard {
    SourceGuard(SOURCE.with(|s| s.replace(source)))
}

/// Adds to this thread's counts: `f` gets them and the current source's index.
pub fn count(f: impl FnOnce(&mut Work, usize)) {
    let k = SOURCE.with(|s| s.get()) as usize;
    WORK.with(|w| f(&mut w.borrow_mut(), k));
}

/// The line search of one solve, iteration by iteration.
#[derive(Clone, Copy, Debug, Default)]
pub struct LineSearches {
    /// Evaluations so far (the start's included).
    pub evaluations: u64,
    /// Most trials an iteration needed.
    pub most_trials: u32,
    /// Per cap n: the evaluations a line search giving up after n trials would have made.
    pub capped: [Option<u64>; 13],
}

impl LineSearches {
    /// One iteration's line search took `trials` evaluations (`failed`: none was accepted).
    pub fn iteration(&mut self, trials: u32, failed: bool) {
        let needed = if failed { trials + 1 } else { trials };
        self.most_trials = self.most_trials.max(needed);
        for n in 1..13u32 {
            if needed > n && self.capped[n as usize].is_none() {
                self.capped[n as usize] = Some(self.evaluations + u64::from(n));
            }
        }
        self.evaluations += u64::from(trials);
    }
}

thread_local! {
    static LAST: Cell<LineSearches> = Cell::new(LineSearches::default());
}

/// Records the current solve's line searches.
pub fn set_line_searches(record: LineSearches) {
    LAST.with(|l| l.set(record));
}

/// Counts the line searches of the solve just ended.
pub fn end_solve(converged: bool) {
    let record = LAST.with(|l| l.replace(LineSearches::default()));
    count(|w, k| {
        if converged {
            w.converged_trials[k][(record.most_trials as usize).min(12)] += 1;
        } else {
            for n in 1..13 {
                w.failed_evaluations_capped[k][n] +=
                    record.capped[n].unwrap_or(record.evaluations.max(1));
            }
        }
    });
}

/// This thread's evaluations so far, of the current source.
pub fn evaluations() -> u64 {
    let k = SOURCE.with(|s| s.get()) as usize;
    WORK.with(|w| w.borrow().evaluations[k])
}

/// The counts of every rayon thread and this one since the last call, and zeroes them.
pub fn take() -> Work {
    let mine = WORK.with(|w| std::mem::take(&mut *w.borrow_mut()));
    let theirs = rayon::broadcast(|_| WORK.with(|w| std::mem::take(&mut *w.borrow_mut())));
    let mut total = mine;
    for w in &theirs {
        total.add(w);
    }
    total
}
