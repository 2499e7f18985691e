//! The MBS20K layout (conventions §3): `<root>/<Town>/<Weather>/<frame>/rgb_0.png …
//! rgb_{N-1}.png, depth_0.png`. Scanning it gives a manifest; the counts per
//! town and weather print like the paper's statistics table; decoding its
//! depth writes `depth_0.exr` and `disp_0_T.png` beside (or mirroring)
//! each `depth_0.png`.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use mbs_core::Rig;
use mbs_core::formats::{DepthFormat, DisparityFormat, carla, rgb};
use mbs_core::geometry::{depth_to_disparity, limit_depth};

use crate::error::DatasetError;
use crate::manifest::{DepthEncoding, DepthInfo, FORMAT, Manifest, Provenance, Sample, Split};

/// The towns held out for testing by default.
pub const DEFAULT_TEST_TOWNS: [&str; 1] = ["Town10"];
/// The depth limit of the authors' loader, in metres.
pub const DEFAULT_MAX_DEPTH_M: f64 = 200.0;

/// The file name of view `k`.
pub fn view_file(k: usize) -> String {
    format!("rgb_{k}.png")
}

/// The file name of the depth image of camera 0.
pub const DEPTH_FILE: &str = "depth_0.png";

/// The name of camera `camera`'s decoded depth in `format`.
pub fn decoded_depth_file(camera: usize, format: DepthFormat) -> String {
    match format {
        DepthFormat::Exr => format!("depth_{camera}.exr"),
        DepthFormat::Pfm => format!("depth_{camera}.pfm"),
        DepthFormat::Png16 => format!("depth_{camera}_mm.png"),
    }
}

/// The name of the disparity of pair `reference:target` decoded from depth,
/// in `format`.
pub fn decoded_disparity_file(reference: usize, target: usize, format: DisparityFormat) -> String {
    format!("disp_{reference}_{target}.{}", format.extension())
}

/// A depth image to decode and the folder its outputs go to.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    /// The CARLA-encoded depth PNG.
    pub encoded: PathBuf,
    /// Where its decoded depth and disparities go.
    pub out_dir: PathBuf,
}

/// Every `depth_0.png` in `root` or below (a whole tree, a town or one
/// frame), sorted by path; outputs beside each, or in the same place under
/// `out`.
pub fn depth_images_in_folder(
    root: &Path,
    out: Option<&Path>,
) -> Result<Vec<DepthImage>, DatasetError> {
    let mut images = Vec::new();
    let mut not_a_file = None;
    // walkdir follows linked towns and stops at link cycles.
    for entry in crate::walk::entries(root) {
        let entry = entry?;
        if entry.file_name() == DEPTH_FILE && !entry.file_type().is_file() {
            not_a_file.get_or_insert_with(|| entry.path().to_path_buf());
        }
        if entry.file_type().is_file() && entry.file_name() == DEPTH_FILE {
            let dir = entry.path().parent().unwrap_or(root);
            let relative = dir.strip_prefix(root).unwrap_or(Path::new(""));
            images.push(DepthImage {
                encoded: entry.path().to_path_buf(),
                out_dir: out.map_or_else(|| dir.to_path_buf(), |o| o.join(relative)),
            });
        }
    }
    if images.is_empty() {
        return Err(match not_a_file {
            Some(path) => DatasetError::Layout {
                path,
                message: format!("is named {DEPTH_FILE} but is not a file"),
            },
            None => DatasetError::Layout {
                path: root.to_path_buf(),
                message: format!("no {DEPTH_FILE} found in this folder or below"),
            },
        });
    }
    Ok(images)
}

/// The depth image of every sample of a manifest read from `path`; outputs
/// beside each, or in the same place under `out` (manifest paths are
/// confined names, so they stay inside it).
pub fn depth_images_in_manifest(
    path: &Path,
    manifest: &Manifest,
    out: Option<&Path>,
) -> Result<Vec<DepthImage>, DatasetError> {
    let images = manifest
        .samples
        .iter()
        .filter_map(|s| s.depth.as_deref())
        .map(|relative| {
            let encoded = crate::manifest::resolve(path, relative);
            let folder = relative.rsplit_once('/').map_or("", |(dir, _)| dir);
            let out_dir = match out {
                Some(o) if folder.is_empty() => o.to_path_buf(),
                Some(o) => mbs_core::confine::join_confined(o, folder)?,
                None => encoded.parent().unwrap_or(Path::new("")).to_path_buf(),
            };
            Ok(DepthImage { encoded, out_dir })
        })
        .collect::<Result<Vec<_>, DatasetError>>()?;
    if images.is_empty() {
        return Err(DatasetError::Manifest {
            path: path.to_path_buf(),
            message: "no sample has a depth image".into(),
        });
    }
    Ok(images)
}

/// What decoding writes for every depth image.
#[derive(Debug, Clone)]
pub struct DepthDecoding {
    /// The rig the disparities are computed for.
    pub rig: Rig,
    /// The camera the depth images belong to.
    pub camera: usize,
    /// The cameras a disparity is written for, against `camera`.
    pub targets: Vec<usize>,
    /// Depth beyond this many metres is invalid.
    pub max_depth_m: f32,
    /// The file format of the depth maps.
    pub depth_format: DepthFormat,
    /// The file format of the disparity maps.
    pub disparity_format: DisparityFormat,
}

impl DepthDecoding {
    /// The decoded depth of `image` and its disparities for each target.
    fn output_files(&self, image: &DepthImage) -> (PathBuf, Vec<(usize, PathBuf)>) {
        let depth_path = image
            .out_dir
            .join(decoded_depth_file(self.camera, self.depth_format));
        let disparities = self
            .targets
            .iter()
            .map(|&t| {
                let name = decoded_disparity_file(self.camera, t, self.disparity_format);
                (t, image.out_dir.join(name))
            })
            .collect();
        (depth_path, disparities)
    }

    /// Every file decoding `image` writes.
    pub fn outputs(&self, image: &DepthImage) -> Vec<PathBuf> {
        let (depth, disparities) = self.output_files(image);
        std::iter::once(depth)
            .chain(disparities.into_iter().map(|(_, path)| path))
            .collect()
    }

    /// Decodes one depth image and writes the outputs it does not have yet
    /// (each atomically); `false` when all were there already.
    pub fn decode(&self, image: &DepthImage) -> Result<bool, DatasetError> {
        let (depth_path, disparities) = self.output_files(image);
        let missing: Vec<(usize, PathBuf)> = disparities
            .into_iter()
            .filter(|(_, path)| !path.exists())
            .collect();
        let depth_missing = !depth_path.exists();
        if !depth_missing && missing.is_empty() {
            return Ok(false);
        }
        let depth = carla::decode_depth(&rgb::read_rgb8_strict(&image.encoded)?);
        if depth_missing {
            let limited = limit_depth(&depth, self.max_depth_m);
            self.depth_format.write(&depth_path, &limited)?;
        }
        for (target, path) in missing {
            let disparity =
                depth_to_disparity(&depth, &self.rig, self.camera, target, self.max_depth_m);
            self.disparity_format.write(&path, &disparity)?;
        }
        Ok(true)
    }
}

/// How to scan an MBS20K tree.
#[derive(Debug, Clone)]
pub struct ScanOptions {
    /// The rig; its size is checked later by `validate`.
    pub rig: Rig,
    /// Towns whose samples go to the test split.
    pub test_towns: Vec<String>,
    /// Depth beyond this is invalid for disparity.
    pub max_depth_m: f64,
}

impl Default for ScanOptions {
    fn default() -> Self {
        ScanOptions {
            rig: Rig::mbs20k(),
            test_towns: DEFAULT_TEST_TOWNS.iter().map(|t| t.to_string()).collect(),
            max_depth_m: DEFAULT_MAX_DEPTH_M,
        }
    }
}

/// The folders in `dir` (links to folders included), sorted; a name that
/// is not UTF-8 is an error naming it.
pub(crate) fn sorted_subdirs(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let io = |source| DatasetError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let mut dirs = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        // `is_dir` follows symbolic links: a linked town is a town.
        if path.is_dir() {
            crate::utf8_file_name(&path)?;
            dirs.push(path);
        }
    }
    dirs.sort();
    Ok(dirs)
}

fn name_of(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Every frame folder of an MBS20K tree (a folder holding `rgb_0.png`, three
/// levels below `root`), sorted.
pub fn frame_dirs(root: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let mut frames = Vec::new();
    for town in sorted_subdirs(root)? {
        for weather in sorted_subdirs(&town)? {
            for frame in sorted_subdirs(&weather)? {
                if frame.join(view_file(0)).is_file() {
                    frames.push(frame);
                }
            }
        }
    }
    Ok(frames)
}

/// Scans an MBS20K tree into a manifest whose paths are relative to `root`
/// (save it as `<root>/manifest.json`). Views are listed as the rig expects
/// them, present or not, so that `validate` reports missing ones.
pub fn scan(root: &Path, options: &ScanOptions) -> Result<Manifest, DatasetError> {
    let frames = frame_dirs(root)?;
    if frames.is_empty() {
        return Err(DatasetError::Layout {
            path: root.to_path_buf(),
            message: "no frames found: expected <root>/<Town>/<Weather>/<frame>/rgb_0.png".into(),
        });
    }
    let samples = frames
        .iter()
        .map(|frame| frame_sample(root, frame, options))
        .collect::<Result<Vec<_>, DatasetError>>()?;
    let has_depth = samples.iter().any(|s| s.depth.is_some());
    Ok(Manifest {
        format: FORMAT.into(),
        name: Some(name_of(
            &std::path::absolute(root).unwrap_or_else(|_| root.to_path_buf()),
        ))
        .filter(|n| !n.is_empty())
        .unwrap_or_else(|| "mbs20k".into()),
        rig: options.rig,
        depth: has_depth.then_some(DepthInfo {
            encoding: DepthEncoding::CarlaRgb,
            camera: 0,
            max_depth_m: options.max_depth_m,
        }),
        samples,
        provenance: Some(Provenance {
            tool: "mbs-tool scan".into(),
            version: env!("CARGO_PKG_VERSION").into(),
            settings: serde_json::json!({ "test_towns": options.test_towns }),
        }),
    })
}

/// The sample of the frame folder `frame` (`<root>/<Town>/<Weather>/<frame>`),
/// its id made of the three folder names.
fn frame_sample(root: &Path, frame: &Path, options: &ScanOptions) -> Result<Sample, DatasetError> {
    let weather_dir = frame.parent().unwrap_or(root);
    let town = name_of(weather_dir.parent().unwrap_or(root));
    let weather = name_of(weather_dir);
    let id = format!("{town}/{weather}/{}", name_of(frame));
    // Ids and paths are confined names (mbs_core::confine).
    mbs_core::confine::check_name(&id).map_err(|why| DatasetError::Layout {
        path: frame.to_path_buf(),
        message: format!("the sample id {id:?} made of its folder names {why}: rename the folder"),
    })?;
    let views = (0..options.rig.num_views)
        .map(|k| format!("{id}/{}", view_file(k)))
        .collect();
    let depth = frame
        .join(DEPTH_FILE)
        .is_file()
        .then(|| format!("{id}/{DEPTH_FILE}"));
    let split = if options.test_towns.contains(&town) {
        Split::Test
    } else {
        Split::Train
    };
    Ok(Sample {
        id,
        split,
        town: Some(town),
        weather: Some(weather),
        sequence: None,
        views,
        depth,
        ground_truth: Vec::new(),
        synthesized_masks: Vec::new(),
        sha256: BTreeMap::new(),
        image_size: None,
    })
}

/// Sample counts per town (rows) and weather (columns).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counts {
    /// `(town, weather) -> count`.
    pub cells: BTreeMap<(String, String), usize>,
}

impl Counts {
    /// Counts the samples of a manifest (samples without town or weather
    /// count under `-`).
    pub fn of(manifest: &Manifest) -> Counts {
        let mut cells = BTreeMap::new();
        for s in &manifest.samples {
            let key = (
                s.town.clone().unwrap_or_else(|| "-".into()),
                s.weather.clone().unwrap_or_else(|| "-".into()),
            );
            *cells.entry(key).or_insert(0) += 1;
        }
        Counts { cells }
    }

    /// The total number of samples.
    pub fn total(&self) -> usize {
        self.cells.values().sum()
    }

    /// A table like the paper's "Statistics of our MBS20K dataset": one row
    /// per town, one column per weather, totals on the right and at the bottom.
    pub fn table(&self) -> String {
        let towns: BTreeSet<&String> = self.cells.keys().map(|(t, _)| t).collect();
        let weathers: BTreeSet<&String> = self.cells.keys().map(|(_, w)| w).collect();
        let width = weathers.iter().map(|w| w.len()).max().unwrap_or(0).max(6);
        let town_width = towns.iter().map(|t| t.len()).max().unwrap_or(0).max(4);
        let mut out = String::new();
        // Writing to a String cannot fail.
        let _ = write!(out, "{:<town_width$}", "#Set");
        for w in &weathers {
            let _ = write!(out, " {w:>width$}");
        }
        let _ = writeln!(out, " {:>width$}", "All");
        for town in &towns {
            let _ = write!(out, "{town:<town_width$}");
            let mut row_total = 0;
            for w in &weathers {
                let n = self
                    .cells
                    .get(&((*town).clone(), (*w).clone()))
                    .copied()
                    .unwrap_or(0);
                row_total += n;
                let _ = write!(out, " {n:>width$}");
            }
            let _ = writeln!(out, " {row_total:>width$}");
        }
        let _ = write!(out, "{:<town_width$}", "All");
        for w in &weathers {
            let n: usize = self
                .cells
                .iter()
                .filter(|((_, cw), _)| cw == *w)
                .map(|(_, n)| n)
                .sum();
            let _ = write!(out, " {n:>width$}");
        }
        let _ = writeln!(out, " {:>width$}", self.total());
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_test_support::files::touch;

    #[test]
    fn scans_layout_assigns_test_split_and_counts() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for (town, weather, frame) in [
            ("Town01", "ClearNoon", "000001"),
            ("Town01", "ClearNoon", "000002"),
            ("Town01", "ClearNight", "000001"),
            ("Town10", "ClearNoon", "000007"),
        ] {
            touch(&root.join(town).join(weather).join(frame).join("rgb_0.png"));
        }
        touch(&root.join("Town01/ClearNoon/000001/depth_0.png"));
        std::fs::create_dir_all(root.join("Town01/ClearNoon/empty")).unwrap();

        let manifest = scan(root, &ScanOptions::default()).unwrap();
        let ids: Vec<&str> = manifest.samples.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "Town01/ClearNight/000001",
                "Town01/ClearNoon/000001",
                "Town01/ClearNoon/000002",
                "Town10/ClearNoon/000007"
            ]
        );
        assert_eq!(manifest.samples[3].split, Split::Test);
        assert_eq!(manifest.samples[0].split, Split::Train);
        assert_eq!(
            manifest.samples[1].depth.as_deref(),
            Some("Town01/ClearNoon/000001/depth_0.png")
        );
        assert_eq!(manifest.samples[0].views.len(), 5);

        let counts = Counts::of(&manifest);
        assert_eq!(counts.total(), 4);
        let table = counts.table();
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(
            lines[0].split_whitespace().collect::<Vec<_>>(),
            ["#Set", "ClearNight", "ClearNoon", "All"]
        );
        assert_eq!(
            lines[1].split_whitespace().collect::<Vec<_>>(),
            ["Town01", "1", "2", "3"]
        );
        assert_eq!(
            lines[3].split_whitespace().collect::<Vec<_>>(),
            ["All", "1", "3", "4"]
        );
    }

    #[test]
    fn empty_tree_is_a_layout_error_naming_the_root() {
        let dir = tempfile::tempdir().unwrap();
        let err = scan(dir.path(), &ScanOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("no frames found") && err.contains(&*dir.path().to_string_lossy()),
            "{err}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn linked_towns_are_followed_and_non_utf8_names_named() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("root");
        touch(
            &dir.path()
                .join("elsewhere/Town10/ClearNoon/000000/rgb_0.png"),
        );
        touch(&root.join("Town01/ClearNoon/000000/rgb_0.png"));
        std::os::unix::fs::symlink(dir.path().join("elsewhere/Town10"), root.join("Town10"))
            .unwrap();
        let frames = frame_dirs(&root).unwrap();
        assert_eq!(frames.len(), 2, "{frames:?}");
        assert!(frames[1].starts_with(root.join("Town10")));

        use std::os::unix::ffi::OsStrExt;
        let odd = root.join(std::ffi::OsStr::from_bytes(b"Town\xff"));
        std::fs::create_dir_all(&odd).unwrap();
        let err = frame_dirs(&root).unwrap_err().to_string();
        assert!(
            err.contains("not valid UTF-8") && err.contains("Town"),
            "{err}"
        );
    }

    #[test]
    fn folder_names_that_break_the_name_rule_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("Town01/Clear:Noon/000000/rgb_0.png"));
        let err = scan(dir.path(), &ScanOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("Clear:Noon") && err.contains("rename the folder"),
            "{err}"
        );
    }

    #[test]
    fn depth_images_walk_past_link_loops_and_name_a_folder_posing_as_one() {
        let dir = tempfile::tempdir().unwrap();
        let frame = dir.path().join("Town01/ClearNoon/000000");
        touch(&frame.join(DEPTH_FILE));
        std::os::unix::fs::symlink(dir.path(), frame.join("loop")).unwrap();
        let images = depth_images_in_folder(dir.path(), None).unwrap();
        assert_eq!(images.len(), 1);
        assert_eq!(images[0].encoded, frame.join(DEPTH_FILE));

        let empty = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(empty.path().join("a").join(DEPTH_FILE)).unwrap();
        let err = depth_images_in_folder(empty.path(), None)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("is named depth_0.png but is not a file"),
            "{err}"
        );
        assert!(
            err.contains(&empty.path().join("a").display().to_string()),
            "{err}"
        );
    }
}
