//! The `clipsat` binary: the library's progress reports drawn as bars on stderr.

use std::cell::RefCell;

use clipsat::ProgressReport;
use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar per task the library reports, on stderr; cleared when the task ends.
#[derive(Debug, Default)]
pub(crate) struct Bars {
    current: RefCell<Option<(String, ProgressBar)>>,
}

impl Bars {
    /// Draws one report: a new bar when the task changes, cleared when it is done.
    pub(crate) fn report(&self, r: ProgressReport<'_>) {
        let mut current = self.current.borrow_mut();
        if current.as_ref().is_none_or(|(task, _)| task != r.task) {
            if let Some((_, old)) = current.take() {
                old.finish_and_clear();
            }
            let bar = ProgressBar::new(r.total);
            if let Ok(style) = ProgressStyle::with_template("{msg} {bar:30} {pos}/{len} {elapsed}")
            {
                bar.set_style(style);
            }
            bar.set_message(r.task.to_string());
            *current = Some((r.task.to_string(), bar));
        }
        if let Some((_, bar)) = current.as_ref() {
            bar.set_length(r.total);
            bar.set_position(r.done);
            if r.done >= r.total {
                bar.finish_and_clear();
            }
        }
        if current.as_ref().is_some_and(|(_, b)| b.is_finished()) {
            *current = None;
        }
    }
}

/// `$progress` (a `clipsat::Progress`) drawing bars on stderr when `$on`, else silent. A macro, since the
/// callback borrows a `Bars` that must outlive it in the caller's frame.
macro_rules! bars {
    ($on:expr, $bars:ident, $report:ident, $progress:ident) => {
        let $bars = $crate::app::progress::Bars::default();
        let $report = |r: clipsat::ProgressReport<'_>| $bars.report(r);
        let $progress = if $on {
            clipsat::Progress::new(&$report)
        } else {
            clipsat::Progress::default()
        };
    };
}
pub(crate) use bars;
