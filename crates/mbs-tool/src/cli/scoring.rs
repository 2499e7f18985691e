//! How `eval` and `benchmark` run the scoring (mbs-eval's
//! [`score_items`]): a progress bar, each failed image named on stderr and
//! a batch summary; and the warning naming frames left unscored for want
//! of usable ground truth.

use std::time::Instant;

use mbs_eval::{Item, Predictor, Progress, Rules, Scored, score_items};

use crate::cli::batch;
use crate::cli::report_error::describe_item_error;

/// Scores `items` under `rules` with a progress bar (see [`score_items`]),
/// each failed image reported on stderr; with the batch's summary.
pub fn score_with_bar(
    items: &[Item],
    predictor: Option<&dyn Predictor>,
    gt_scale: Option<f32>,
    rules: &Rules,
) -> (Scored, batch::Summary) {
    let start = Instant::now();
    let bar = batch::progress_bar(items.len(), "images");
    let scored = score_items(items, predictor, gt_scale, rules, &|progress| {
        bar.inc(1);
        if let Progress::Failed { name, error } = progress {
            bar.suspend(|| eprintln!("error: {}", describe_item_error(name, error)));
        }
    });
    bar.finish_and_clear();
    let summary = batch::Summary {
        done: scored.images.len(),
        skipped: 0,
        failed: scored.failed.len(),
        elapsed: start.elapsed(),
    };
    (scored, summary)
}

/// Prints a warning line naming the `unscored` frames of `label`, if any.
pub fn warn_unscored(label: &str, unscored: &[String]) {
    if let Some(line) = unscored_line(label, unscored) {
        eprintln!("{line}");
    }
}

/// The warning line for `unscored` frames of `label` (the first 20 named).
fn unscored_line(label: &str, unscored: &[String]) -> Option<String> {
    const NAMED: usize = 20;
    if unscored.is_empty() {
        return None;
    }
    let mut names = unscored[..unscored.len().min(NAMED)].join(", ");
    if unscored.len() > NAMED {
        names += &format!(" and {} more", unscored.len() - NAMED);
    }
    Some(format!(
        "warning: {label}: {} frame(s) not scored, without usable ground truth (missing, or \
         not a regular file): {names}",
        unscored.len()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_unscored_line_names_the_first_twenty_frames() {
        assert_eq!(unscored_line("KITTI 2015 training", &[]), None);
        let two = ["a".to_string(), "b".to_string()];
        assert_eq!(
            unscored_line("ETH3D x", &two).unwrap(),
            "warning: ETH3D x: 2 frame(s) not scored, without usable ground truth (missing, or \
             not a regular file): a, b"
        );
        let many: Vec<String> = (0..23).map(|i| format!("f{i}")).collect();
        let line = unscored_line("x", &many).unwrap();
        assert!(line.ends_with("f18, f19 and 3 more"), "{line}");
    }
}
