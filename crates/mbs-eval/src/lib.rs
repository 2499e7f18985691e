//! Scoring predicted disparities against ground truth: the error sums and
//! metrics (conventions §6), the named protocols of the field and their
//! rules per dataset, one image scored under a protocol, the reports of a
//! set (per image, averaged per image, pooled over pixels), frame lists,
//! and the run that scores a source's pairs with a progress callback.
//! `eval`, `benchmark`, the demo and the trainer's validation score
//! through it.

mod error;
mod frames;
mod listing;
mod prediction;
mod protocol;
mod protocol_report;
mod report;
mod run;
mod score;
mod sums;

pub use error::EvalError;
pub use frames::FrameList;
pub use listing::{Listing, check_listed};
pub use mbs_dataset::benchmark::Dataset;
pub use prediction::interpolate_background;
pub use protocol::{
    Aggregation, Figure, GtRange, PredictionRule, Protocol, ProtocolError, Regions, Rules,
    rules_for,
};
pub use protocol_report::ProtocolReport;
pub use run::{
    Item, Prediction, Predictor, Progress, Scored, SourceScores, items, score_items,
    score_predictions, score_truth,
};
pub use score::{Frame, ImageScore, Summary, Tally};
pub use sums::{
    D1_ABS_PX, D1_REL, DEFAULT_OUT_THRESHOLDS, ErrorSums, MeanMetrics, Metrics, MetricsError,
    Region, RegionSums,
};
