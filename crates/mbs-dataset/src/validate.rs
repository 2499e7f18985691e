//! `validate`: a manifest against the schema and against the files on disk.
//! Every problem names the sample and the file; the report is clean only
//! when nothing was found.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;

use image::ColorType;
use mbs_core::Rig;
use rayon::prelude::*;
use serde::Serialize;

use crate::checksum::sha256_file;
use crate::manifest::{FileRole, Sample, integral_numbers_as_integers, resolve};
use crate::probe::{PixelType, ProbeError, probe};
use crate::schema::manifest_schema_issues;

/// How thoroughly to check.
#[derive(Debug, Clone, Copy, Default)]
pub struct ValidateOptions {
    /// Decode every pixel of every file instead of reading headers.
    pub deep: bool,
}

/// The kind of a problem, stable for machine-readable reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProblemKind {
    /// The manifest cannot be read or is not JSON.
    Unreadable,
    /// The manifest breaks the JSON Schema.
    Schema,
    /// Two samples share an id.
    DuplicateId,
    /// A sample has a different number of views than the rig.
    ViewCount,
    /// A camera index outside the rig.
    BadCamera,
    /// A referenced file does not exist.
    MissingFile,
    /// A file ends before its data does.
    Truncated,
    /// A file cannot be decoded.
    Corrupt,
    /// An image's size differs from the rig's.
    WrongSize,
    /// An image has the wrong pixel type for its role (e.g. 16-bit depth).
    WrongPixelType,
    /// A file's SHA-256 differs from the manifest's.
    ChecksumMismatch,
    /// A sample whose files could not be checked (the reason says why).
    Unchecked,
}

/// One problem found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Problem {
    /// The sample concerned, when there is one.
    pub sample: Option<String>,
    /// The file (relative to the manifest) or JSON pointer concerned.
    pub path: Option<String>,
    /// The kind of problem.
    pub kind: ProblemKind,
    /// What is wrong, in words.
    pub message: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(sample) = &self.sample {
            write!(f, "sample {sample}: ")?;
        }
        if let Some(path) = &self.path {
            write!(f, "{path}: ")?;
        }
        write!(f, "{}", self.message)
    }
}

/// The outcome of validating one manifest.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The manifest checked.
    pub manifest: String,
    /// Whether pixels were decoded.
    pub deep: bool,
    /// Samples in the manifest.
    pub samples: usize,
    /// Distinct files checked on disk.
    pub files_checked: usize,
    /// Every problem found, in sample order.
    pub problems: Vec<Problem>,
}

impl Report {
    /// True when no problem was found.
    pub fn is_clean(&self) -> bool {
        self.problems.is_empty()
    }
}

fn problem(
    sample: Option<&str>,
    path: Option<&str>,
    kind: ProblemKind,
    message: impl Into<String>,
) -> Problem {
    Problem {
        sample: sample.map(str::to_string),
        path: path.map(str::to_string),
        kind,
        message: message.into(),
    }
}

/// Receives the progress of a validation (for progress bars).
pub trait Progress: Sync {
    /// The number of samples about to be checked on disk.
    fn start(&self, _samples: usize) {}
    /// One more sample has been checked.
    fn advance(&self) {}
}

/// No progress reporting.
impl Progress for () {}

/// Validates the manifest at `manifest_path`, reporting to `progress` as
/// samples are checked on disk.
pub fn validate_manifest(
    manifest_path: &Path,
    options: ValidateOptions,
    progress: &dyn Progress,
) -> Report {
    let mut report = Report {
        manifest: manifest_path.display().to_string(),
        deep: options.deep,
        samples: 0,
        files_checked: 0,
        problems: Vec::new(),
    };
    let mut document = match read_document(manifest_path) {
        Ok(doc) => doc,
        Err(message) => {
            report
                .problems
                .push(problem(None, None, ProblemKind::Unreadable, message));
            return report;
        }
    };
    // As `Manifest::load` reads it: `1.0` is an integer to the schema and
    // to the model alike.
    integral_numbers_as_integers(&mut document);
    let raw_samples = document["samples"].as_array().cloned().unwrap_or_default();
    report.samples = raw_samples.len();
    let bad_indices = report_schema_issues(&document, &raw_samples, &mut report.problems);
    let Ok(rig) = serde_json::from_value::<Rig>(document["rig"].clone()) else {
        // Without a rig nothing on disk can be judged; the schema problem says why.
        report.problems.push(problem(
            None,
            Some("/rig"),
            ProblemKind::Unchecked,
            format!(
                "no file of the {} sample(s) checked: the rig cannot be read",
                report.samples
            ),
        ));
        return report;
    };
    let samples = readable_samples(&raw_samples, &bad_indices, &mut report.problems);
    report_duplicate_ids(&samples, &mut report.problems);
    progress.start(samples.len());
    let per_sample: Vec<(usize, Vec<Problem>)> = samples
        .par_iter()
        .map(|s| {
            let result = check_sample(manifest_path, &rig, s, options);
            progress.advance();
            result
        })
        .collect();
    for (files, problems) in per_sample {
        report.files_checked += files;
        report.problems.extend(problems);
    }
    report
}

/// The manifest's JSON, or why it cannot be had (unreadable, not JSON).
fn read_document(manifest_path: &Path) -> Result<serde_json::Value, String> {
    mbs_core::regular::read_text(manifest_path)
        .map_err(|e| e.to_string())
        .and_then(|text| serde_json::from_str(&text).map_err(|e| format!("not valid JSON: {e}")))
}

/// The id of the `i`-th raw sample, when it has one.
fn raw_sample_id(raw_samples: &[serde_json::Value], i: usize) -> Option<String> {
    raw_samples
        .get(i)
        .and_then(|s| s["id"].as_str())
        .map(str::to_string)
}

/// Adds a problem for each way `document` breaks the schema; returns the
/// indices of the samples that break it.
fn report_schema_issues(
    document: &serde_json::Value,
    raw_samples: &[serde_json::Value],
    problems: &mut Vec<Problem>,
) -> BTreeSet<usize> {
    let schema_issues = manifest_schema_issues(document);
    for issue in &schema_issues {
        let sample = issue
            .sample_index()
            .and_then(|i| raw_sample_id(raw_samples, i));
        let pointer = if issue.pointer.is_empty() {
            "/"
        } else {
            &issue.pointer
        };
        problems.push(problem(
            sample.as_deref(),
            Some(pointer),
            ProblemKind::Schema,
            format!("schema: {}", issue.message),
        ));
    }
    schema_issues
        .iter()
        .filter_map(|i| i.sample_index())
        .collect()
}

/// The samples whose files can be checked on disk. Every other sample (one
/// that breaks the schema or cannot be read) gets a problem saying its
/// files were not checked, so that none goes unmentioned.
fn readable_samples(
    raw_samples: &[serde_json::Value],
    bad_indices: &BTreeSet<usize>,
    problems: &mut Vec<Problem>,
) -> Vec<Sample> {
    let mut samples: Vec<Sample> = Vec::with_capacity(raw_samples.len());
    for (i, raw) in raw_samples.iter().enumerate() {
        let label = raw_sample_id(raw_samples, i).unwrap_or_else(|| format!("#{i}"));
        let reason = if bad_indices.contains(&i) {
            "it breaks the schema (see above)".to_string()
        } else {
            match serde_json::from_value(raw.clone()) {
                Ok(sample) => {
                    samples.push(sample);
                    continue;
                }
                Err(e) => format!("it cannot be read: {e}"),
            }
        };
        problems.push(problem(
            Some(&label),
            Some(&format!("/samples/{i}")),
            ProblemKind::Unchecked,
            format!("files not checked: {reason}"),
        ));
    }
    samples
}

/// Adds one problem for each id that two or more samples share.
fn report_duplicate_ids(samples: &[Sample], problems: &mut Vec<Problem>) {
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for s in samples {
        let count = seen.entry(s.id.as_str()).or_insert(0);
        *count += 1;
        if *count == 2 {
            problems.push(problem(
                Some(&s.id),
                None,
                ProblemKind::DuplicateId,
                "duplicate sample id",
            ));
        }
    }
}

/// Checks one sample's structure and files; returns the files checked and the problems.
fn check_sample(
    manifest_path: &Path,
    rig: &Rig,
    sample: &Sample,
    options: ValidateOptions,
) -> (usize, Vec<Problem>) {
    let id = Some(sample.id.as_str());
    let mut problems = structure_problems(rig, sample);
    let mut checked = BTreeSet::new();
    for (role, rel) in sample.files() {
        if checked.insert(rel) {
            problems.extend(check_file(
                manifest_path,
                sample.size(rig),
                id,
                role,
                rel,
                options,
            ));
        }
    }
    for (rel, expected) in &sample.sha256 {
        let path = resolve(manifest_path, rel);
        match sha256_file(&path) {
            Ok(actual) if actual == *expected => {}
            Ok(actual) => problems.push(problem(
                id,
                Some(rel),
                ProblemKind::ChecksumMismatch,
                format!("sha256 is {actual}, the manifest says {expected}"),
            )),
            Err(_) if checked.contains(rel.as_str()) => {} // already reported as missing
            Err(e) => problems.push(problem(
                id,
                Some(rel),
                ProblemKind::MissingFile,
                e.to_string(),
            )),
        }
    }
    (checked.len(), problems)
}

/// A sample's problems that need no file: its number of views and of
/// synthesized masks against the rig's, and pairs that are not two
/// distinct cameras of the rig.
fn structure_problems(rig: &Rig, sample: &Sample) -> Vec<Problem> {
    let id = Some(sample.id.as_str());
    let mut problems = Vec::new();
    if sample.views.len() != rig.num_views {
        problems.push(problem(
            id,
            None,
            ProblemKind::ViewCount,
            format!(
                "{} views, the rig has {}",
                sample.views.len(),
                rig.num_views
            ),
        ));
    }
    if !sample.synthesized_masks.is_empty() && sample.synthesized_masks.len() != sample.views.len()
    {
        problems.push(problem(
            id,
            None,
            ProblemKind::ViewCount,
            format!(
                "{} synthesized masks for {} views",
                sample.synthesized_masks.len(),
                sample.views.len()
            ),
        ));
    }
    for gt in &sample.ground_truth {
        if gt.reference >= rig.num_views || gt.target >= rig.num_views || gt.reference == gt.target
        {
            problems.push(problem(
                id,
                Some(&gt.disparity),
                ProblemKind::BadCamera,
                format!(
                    "pair ({}, {}) is not two distinct cameras of a {}-camera rig",
                    gt.reference, gt.target, rig.num_views
                ),
            ));
        }
    }
    problems
}

fn check_file(
    manifest_path: &Path,
    size: (u32, u32),
    id: Option<&str>,
    role: FileRole,
    rel: &str,
    options: ValidateOptions,
) -> Option<Problem> {
    let info = match probe(&resolve(manifest_path, rel), options.deep) {
        Ok(info) => info,
        Err(e) => {
            let kind = match e {
                ProbeError::Missing => ProblemKind::MissingFile,
                ProbeError::Truncated(_) => ProblemKind::Truncated,
                ProbeError::Corrupt(_) => ProblemKind::Corrupt,
            };
            return Some(problem(id, Some(rel), kind, e.to_string()));
        }
    };
    if (info.width, info.height) != size {
        return Some(problem(
            id,
            Some(rel),
            ProblemKind::WrongSize,
            format!(
                "image is {}x{}, the manifest says {}x{}",
                info.width, info.height, size.0, size.1
            ),
        ));
    }
    let pixel_ok = match (role, info.pixels) {
        (FileRole::View, PixelType::Raster(c)) => {
            matches!(c, ColorType::Rgb8 | ColorType::Rgba8 | ColorType::L8)
        }
        (FileRole::Depth, PixelType::Raster(c)) => c == ColorType::Rgb8,
        (FileRole::Disparity, PixelType::Float) => true,
        (FileRole::Disparity, PixelType::Raster(c)) => c == ColorType::L16,
        (FileRole::Mask, PixelType::Raster(c)) => c == ColorType::L8,
        _ => false,
    };
    (!pixel_ok).then(|| {
        let expected = match role {
            FileRole::View => "an 8-bit colour image",
            FileRole::Depth => "an 8-bit RGB CARLA depth PNG",
            FileRole::Disparity => "a PFM/EXR float map or a 16-bit KITTI PNG",
            FileRole::Mask => "an 8-bit greyscale mask",
        };
        let found = match info.pixels {
            PixelType::Raster(c) => format!("{c:?}"),
            PixelType::Float => "a float map".into(),
        };
        problem(
            id,
            Some(rel),
            ProblemKind::WrongPixelType,
            format!("expected {expected}, found {found}"),
        )
    })
}
