//! Parallel batches over files: a progress bar, per-item errors that do not
//! stop the batch, and a summary (done / skipped / failed, items per second).

use std::time::{Duration, Instant};

use crate::cli::report_error::describe_item;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

/// What happened to one item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The item was processed.
    Done,
    /// Its outputs already existed (a resumed run).
    Skipped,
}

/// Counts of a finished batch.
#[derive(Debug, Clone, Copy)]
pub struct Summary {
    /// Items processed.
    pub done: usize,
    /// Items skipped because their outputs were complete.
    pub skipped: usize,
    /// Items that failed.
    pub failed: usize,
    /// Wall time of the batch.
    pub elapsed: Duration,
}

impl Summary {
    /// Processed items per second.
    pub fn rate(&self) -> f64 {
        self.done as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }

    /// Prints the summary line for `label` ("images", "frames"…) and turns
    /// failures into an error, so the process exits non-zero.
    pub fn finish(&self, command: &str, label: &str) -> anyhow::Result<()> {
        eprintln!(
            "{command}: {} done, {} skipped, {} failed in {:.2} s ({:.1} {label}/s)",
            self.done,
            self.skipped,
            self.failed,
            self.elapsed.as_secs_f64(),
            self.rate()
        );
        if self.failed > 0 {
            anyhow::bail!(
                "{} of {} {label} failed (see above)",
                self.failed,
                self.done + self.skipped + self.failed
            );
        }
        Ok(())
    }
}

/// A progress bar on stderr for `len` items (hidden when stderr is not a terminal).
pub fn progress_bar(len: usize, label: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    let template = format!(
        "{{spinner}} [{{elapsed_precise}}] {{wide_bar}} {{pos}}/{{len}} {label} ({{per_sec}}, ETA {{eta}})"
    );
    // The template is a constant apart from the label, which has no braces.
    if let Ok(style) = ProgressStyle::with_template(&template) {
        bar.set_style(style);
    }
    bar
}

/// Runs `work` on every item in parallel with a progress bar and returns
/// each item's result, in order. A failing item is reported on stderr with
/// its name, gives `None` and does not stop the others; the summary counts
/// successes as done.
pub fn map<T, R, W>(
    items: &[T],
    label: &str,
    name: impl Fn(&T) -> String + Sync,
    work: W,
) -> (Vec<Option<R>>, Summary)
where
    T: Sync,
    R: Send,
    W: Fn(&T) -> anyhow::Result<R> + Sync,
{
    map_items(items, label, name, work, true)
}

/// Runs `work` on every item as [`map`] does, one item at a time, so that
/// each has the machine to itself (work that is timed), counting the items
/// whose outputs were already there as skipped.
pub fn run_in_order<T, W>(
    items: &[T],
    label: &str,
    name: impl Fn(&T) -> String + Sync,
    work: W,
) -> Summary
where
    T: Sync,
    W: Fn(&T) -> anyhow::Result<Outcome> + Sync,
{
    count_skipped(map_items(items, label, name, work, false))
}

fn map_items<T, R, W>(
    items: &[T],
    label: &str,
    name: impl Fn(&T) -> String + Sync,
    work: W,
    parallel: bool,
) -> (Vec<Option<R>>, Summary)
where
    T: Sync,
    R: Send,
    W: Fn(&T) -> anyhow::Result<R> + Sync,
{
    let start = Instant::now();
    let bar = progress_bar(items.len(), label);
    let one = |item: &T| {
        let result = work(item);
        bar.inc(1);
        result
            .map_err(|e| {
                bar.suspend(|| eprintln!("error: {}", describe_item(&name(item), &e)));
            })
            .ok()
    };
    let results: Vec<Option<R>> = match parallel {
        true => items.par_iter().map(one).collect(),
        false => items.iter().map(one).collect(),
    };
    bar.finish_and_clear();
    let failed = results.iter().filter(|r| r.is_none()).count();
    let summary = Summary {
        done: items.len() - failed,
        skipped: 0,
        failed,
        elapsed: start.elapsed(),
    };
    (results, summary)
}

/// The summary of a batch with the items whose outcome was
/// [`Outcome::Skipped`] moved from done to skipped.
fn count_skipped((outcomes, mut summary): (Vec<Option<Outcome>>, Summary)) -> Summary {
    summary.skipped = outcomes
        .iter()
        .filter(|o| **o == Some(Outcome::Skipped))
        .count();
    summary.done -= summary.skipped;
    summary
}

/// Runs `work` on every item in parallel, as [`map`] does, counting the
/// items whose outputs were already there as skipped.
pub fn run<T, W>(items: &[T], label: &str, name: impl Fn(&T) -> String + Sync, work: W) -> Summary
where
    T: Sync,
    W: Fn(&T) -> anyhow::Result<Outcome> + Sync,
{
    count_skipped(map(items, label, name, work))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_outcomes_and_keeps_going_after_errors() {
        let items: Vec<u32> = (0..10).collect();
        let summary = run(
            &items,
            "items",
            |i| i.to_string(),
            |i| match i % 3 {
                0 => Ok(Outcome::Done),
                1 => Ok(Outcome::Skipped),
                _ => anyhow::bail!("item {i} is bad"),
            },
        );
        assert_eq!((summary.done, summary.skipped, summary.failed), (4, 3, 3));
        let err = summary.finish("test", "items").unwrap_err().to_string();
        assert_eq!(err, "3 of 10 items failed (see above)");
    }
}
