//! Beside every stage: how long work (a bake) reports how far it is. The library calls the caller's
//! callback and draws nothing itself; the `clipsat` binary turns the reports into progress bars.

/// One report of long work: which task, and how far it is (`done` of `total` units: rows, tiles, bands).
/// A task ends with a report whose `done` equals its `total`; the next task may then begin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct ProgressReport<'a> {
    /// What is being done, in words ("baking LOD tables").
    pub task: &'a str,
    /// Units done.
    pub done: u64,
    /// Units in all (may change while the task learns its size; never 0).
    pub total: u64,
}

/// Where long work reports its progress: a callback of the caller's, or nowhere
/// ([`Progress::default`]). Cheap to copy; handed down by value.
#[derive(Clone, Copy, Default)]
pub struct Progress<'a> {
    report: Option<&'a dyn Fn(ProgressReport<'_>)>,
}

impl std::fmt::Debug for Progress<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.report.is_some() {
            "Progress(callback)"
        } else {
            "Progress(none)"
        })
    }
}

impl<'a> Progress<'a> {
    /// Reports go to `report`, called on the thread doing the work.
    pub fn new(report: &'a dyn Fn(ProgressReport<'_>)) -> Self {
        Self {
            report: Some(report),
        }
    }

    /// A meter for one task of `total` units.
    pub(crate) fn task(self, task: &'static str, total: u64) -> Meter<'a> {
        let m = Meter {
            progress: self,
            task,
            done: 0,
            total,
        };
        m.send();
        m
    }
}

/// The progress of one task: counts units and reports them.
#[derive(Debug)]
pub(crate) struct Meter<'a> {
    progress: Progress<'a>,
    task: &'static str,
    done: u64,
    total: u64,
}

impl Meter<'_> {
    fn send(&self) {
        // A task of unknown size says nothing until it learns it.
        if self.total == 0 {
            return;
        }
        if let Some(report) = self.progress.report {
            report(ProgressReport {
                task: self.task,
                done: self.done.min(self.total),
                total: self.total,
            });
        }
    }

    /// `n` more units done.
    pub(crate) fn inc(&mut self, n: u64) {
        self.done = self.done.saturating_add(n);
        self.send();
    }

    /// Units done so far, set.
    pub(crate) fn set_done(&mut self, done: u64) {
        self.done = done;
        self.send();
    }

    /// The task's size, learnt late.
    pub(crate) fn set_total(&mut self, total: u64) {
        self.total = total;
        self.send();
    }

    /// Starts the next task of the same work: the current one ends.
    pub(crate) fn next(&mut self, task: &'static str, total: u64) {
        self.finish();
        *self = self.progress.task(task, total);
    }

    /// Ends the task (its last report has `done == total`).
    pub(crate) fn finish(&mut self) {
        if self.done < self.total {
            self.done = self.total;
            self.send();
        }
    }
}
