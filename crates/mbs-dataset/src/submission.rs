//! The files the benchmarks' evaluation servers accept, written as their
//! documentation lays them out, with the time each prediction took:
//!
//! - KITTI 2015: `disp_0/<frame>.png`, 16-bit, disparity × 256 rounded,
//!   0 = no prediction; zipped as `kitti_submission.zip` with `disp_0/` at
//!   its root. KITTI 2012: the same PNGs at the archive's root (its
//!   devkit's readme; it reads `<frame>.png` from the unpacked folder).
//!   The servers take no timing file: the time is entered in their form.
//! - Middlebury MiddEval3: `<split>/<Scene>/disp0<NAME>.pfm` (float PFM,
//!   `inf` = no prediction; `disp0<NAME>_s.pfm` for a sparse map) and
//!   `time<NAME>.txt` (seconds), the split folder named as the input's
//!   (`testH`, `trainingH`, …); zipped as `middlebury_submission.zip` with
//!   every split of the method found in the folder, so that a run per
//!   split into one folder makes one archive of all.
//! - ETH3D two-view: `low_res_two_view/<scene>.pfm` and `<scene>.txt`
//!   holding `runtime <seconds>`; zipped as `eth3d_submission.zip`.
//!
//! Every file is written atomically, and a pair counts as written only
//! when each of its files is complete (an image that decodes to its end,
//! a timing file that holds a number); the archive is made last from the
//! files present, so a resumed run's archive holds every pair.

use std::io::Write;
use std::path::{Path, PathBuf};

use mbs_core::FloatImage;
use mbs_core::atomic::{write_atomic, write_bytes_atomic};
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::png16::write_kitti_disparity;

use crate::DatasetError;
use crate::benchmark::Benchmark;
use crate::kitti::{KittiFolder, KittiVersion};

/// The method name MiddEval3's own ground truth is stored under
/// (`disp0GT.pfm`): a submission named so would overwrite it.
const MIDDLEBURY_GROUND_TRUTH: &str = "GT";

/// A benchmark server's submission layout.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SubmissionLayout {
    /// KITTI 2012 or 2015 stereo.
    Kitti(KittiVersion),
    /// Middlebury MiddEval3: the method's name (letters and digits, as
    /// the files are named after it) and the split folder's name.
    Middlebury {
        /// The method's name in the file names.
        method: String,
        /// The split folder, e.g. `testH`.
        split: String,
        /// Whether the maps leave unmatched pixels invalid (`inf`): then
        /// they take MiddEval3's sparse name, `disp0<NAME>_s.pfm`.
        sparse: bool,
    },
    /// ETH3D two-view (low resolution).
    Eth3d,
}

impl SubmissionLayout {
    /// The benchmarks whose evaluation servers take submissions.
    pub const SERVERS: [Benchmark; 3] = [Benchmark::Kitti, Benchmark::Middlebury, Benchmark::Eth3d];

    /// The layout of a submission of `benchmark`'s test folder `dir`:
    /// KITTI's year from the folder's view folders; Middlebury's split
    /// from the folder's name (resolved, so `.` names it) and the
    /// `method`'s name, which it needs ([`SubmissionLayout::middlebury`]).
    /// A benchmark without a server is an error.
    pub fn for_folder(
        benchmark: Benchmark,
        dir: &Path,
        method: Option<&str>,
        sparse: bool,
    ) -> Result<Self, DatasetError> {
        let refused = |message: String| DatasetError::Layout {
            path: dir.to_path_buf(),
            message,
        };
        match benchmark {
            Benchmark::Kitti => Ok(SubmissionLayout::Kitti(KittiFolder::open(dir)?.version)),
            Benchmark::Eth3d => Ok(SubmissionLayout::Eth3d),
            Benchmark::Middlebury => {
                let method = method.ok_or_else(|| {
                    refused("a Middlebury submission needs the method's name".into())
                })?;
                let split = dir.canonicalize().map_err(|source| DatasetError::Io {
                    path: dir.to_path_buf(),
                    source,
                })?;
                let split = split.file_name().ok_or_else(|| {
                    refused("is not a MiddEval3 split folder (testH, trainingQ, ...)".into())
                })?;
                Self::middlebury(method, &split.to_string_lossy(), sparse).map_err(refused)
            }
            Benchmark::DrivingStereo | Benchmark::SceneFlow => Err(refused(format!(
                "{benchmark} has no evaluation server taking submissions"
            ))),
        }
    }

    /// Middlebury's layout for `method` and the split folder `split`
    /// (`sparse` maps take the `_s` name); a name with anything but ASCII
    /// letters and digits is refused, since MiddEval3's scripts read it
    /// back from the file names, and so is `GT`, the ground truth's name.
    pub fn middlebury(method: &str, split: &str, sparse: bool) -> Result<Self, String> {
        if method.is_empty() || !method.chars().all(|c| c.is_ascii_alphanumeric()) {
            return Err(format!(
                "`{method}` cannot name a Middlebury method: use letters and digits only \
                 (it becomes disp0{method}.pfm)"
            ));
        }
        if method.eq_ignore_ascii_case(MIDDLEBURY_GROUND_TRUTH) {
            return Err(format!(
                "`{method}` cannot name a Middlebury method: disp0{method}.pfm is the name of \
                 MiddEval3's ground truth, which the submission would overwrite"
            ));
        }
        Ok(SubmissionLayout::Middlebury {
            method: method.to_string(),
            split: split.to_string(),
            sparse,
        })
    }

    /// The files of pair `id`, relative to the submission folder (as they
    /// lie in the archive): the disparity first, then its timing file
    /// where the layout has one.
    pub fn files(&self, id: &str) -> Vec<PathBuf> {
        match self {
            SubmissionLayout::Kitti(KittiVersion::Kitti2015) => {
                vec![Path::new("disp_0").join(format!("{id}.png"))]
            }
            SubmissionLayout::Kitti(KittiVersion::Kitti2012) => vec![format!("{id}.png").into()],
            SubmissionLayout::Middlebury {
                method,
                split,
                sparse,
            } => {
                let scene = Path::new(split).join(id);
                let suffix = if *sparse { "_s" } else { "" };
                vec![
                    scene.join(format!("disp0{method}{suffix}.pfm")),
                    scene.join(format!("time{method}.txt")),
                ]
            }
            SubmissionLayout::Eth3d => {
                let folder = Path::new("low_res_two_view");
                vec![
                    folder.join(format!("{id}.pfm")),
                    folder.join(format!("{id}.txt")),
                ]
            }
        }
    }

    /// Whether every file of pair `id` is in `out` and complete (a resumed
    /// run skips it): each map decodes to its last pixel, each timing file
    /// holds a number.
    pub fn is_written(&self, out: &Path, id: &str) -> bool {
        let runtime_prefix = matches!(self, SubmissionLayout::Eth3d);
        self.files(id)
            .iter()
            .all(|f| is_complete(&out.join(f), runtime_prefix))
    }

    /// Every file a run over pairs `ids` writes under `out`, the archive
    /// last: the paths a command checks before it writes anything.
    pub fn outputs(&self, out: &Path, ids: &[String]) -> Vec<PathBuf> {
        ids.iter()
            .flat_map(|id| self.files(id))
            .map(|file| out.join(file))
            .chain([out.join(self.archive_name())])
            .collect()
    }

    /// Writes pair `id`'s disparity and the `seconds` its prediction took
    /// under `out`, each file atomically.
    pub fn write(
        &self,
        out: &Path,
        id: &str,
        disparity: &FloatImage,
        seconds: f64,
    ) -> Result<(), DatasetError> {
        let files: Vec<PathBuf> = self.files(id).iter().map(|f| out.join(f)).collect();
        match self {
            SubmissionLayout::Kitti(_) => write_kitti_disparity(&files[0], disparity)?,
            SubmissionLayout::Middlebury { .. } => {
                write_pfm_grey(&files[0], disparity, Endian::Little)?;
                write_bytes_atomic(&files[1], format!("{seconds:.6}\n").as_bytes())?;
            }
            SubmissionLayout::Eth3d => {
                write_pfm_grey(&files[0], disparity, Endian::Little)?;
                write_bytes_atomic(&files[1], format!("runtime {seconds:.6}\n").as_bytes())?;
            }
        }
        Ok(())
    }

    /// For Middlebury, the files of the method's complete scenes in the
    /// other split of the same resolution in `out` (`trainingH` for
    /// `testH` and the other way round: one upload is one resolution);
    /// nothing for the other layouts.
    fn other_splits(
        &self,
        out: &Path,
        ours: &dyn Fn(&Path) -> bool,
    ) -> Result<Vec<PathBuf>, DatasetError> {
        let SubmissionLayout::Middlebury {
            method,
            split,
            sparse,
        } = self
        else {
            return Ok(Vec::new());
        };
        let other = if let Some(resolution) = split.strip_prefix("test") {
            format!("training{resolution}")
        } else if let Some(resolution) = split.strip_prefix("training") {
            format!("test{resolution}")
        } else {
            return Ok(Vec::new());
        };
        if !out.join(&other).is_dir() {
            return Ok(Vec::new());
        }
        let layout = SubmissionLayout::Middlebury {
            method: method.clone(),
            split: other.clone(),
            sparse: *sparse,
        };
        let mut files = Vec::new();
        for scene in sorted_folders(&out.join(&other))? {
            let scene_files = layout.files(&scene);
            if layout.is_written(out, &scene) && scene_files.iter().all(|f| ours(&out.join(f))) {
                files.extend(scene_files);
            }
        }
        Ok(files)
    }

    /// The archive's file name.
    pub fn archive_name(&self) -> &'static str {
        match self {
            SubmissionLayout::Kitti(_) => "kitti_submission.zip",
            SubmissionLayout::Middlebury { .. } => "middlebury_submission.zip",
            SubmissionLayout::Eth3d => "eth3d_submission.zip",
        }
    }

    /// Zips the files of pairs `ids` found under `out` into `out`'s
    /// archive (paths relative to `out`, `/`-separated, in `ids`' order;
    /// for Middlebury, after them, the method's complete scenes of the
    /// other splits in `out` whose files `ours` says this tool wrote);
    /// returns its path. A pair whose files are missing is an error naming
    /// the file.
    pub fn archive(
        &self,
        out: &Path,
        ids: &[String],
        ours: &dyn Fn(&Path) -> bool,
    ) -> Result<PathBuf, DatasetError> {
        let path = out.join(self.archive_name());
        let mut entries = Vec::new();
        let mut files: Vec<PathBuf> = ids.iter().flat_map(|id| self.files(id)).collect();
        files.extend(self.other_splits(out, ours)?);
        for file in files {
            let bytes = mbs_core::regular::read_bytes(&out.join(&file))?;
            let name = file
                .components()
                .map(|c| c.as_os_str().to_string_lossy())
                .collect::<Vec<_>>()
                .join("/");
            entries.push((name, bytes));
        }
        write_atomic(&path, |writer| {
            let mut zip = zip::ZipWriter::new(writer);
            let options = zip::write::SimpleFileOptions::default()
                .compression_method(zip::CompressionMethod::Deflated);
            for (name, bytes) in &entries {
                zip.start_file(name.as_str(), options)
                    .map_err(std::io::Error::other)?;
                zip.write_all(bytes)?;
            }
            zip.finish().map_err(std::io::Error::other)?;
            Ok(())
        })?;
        Ok(path)
    }
}

/// The names of the folders in `dir`, sorted.
fn sorted_folders(dir: &Path) -> Result<Vec<String>, DatasetError> {
    Ok(crate::mbs20k::sorted_subdirs(dir)?
        .iter()
        .filter_map(|path| Some(path.file_name()?.to_string_lossy().into_owned()))
        .collect())
}

/// Whether the submission file `path` is complete: a map that decodes to
/// its last pixel, a timing file that holds a number (`runtime N` where
/// `runtime_prefix`, ETH3D's form; the number alone otherwise).
fn is_complete(path: &Path, runtime_prefix: bool) -> bool {
    let is_text = path.extension().is_some_and(|e| e == "txt");
    if !is_text {
        return crate::probe::probe(path, false).is_ok();
    }
    mbs_core::regular::read_text(path).is_ok_and(|text| {
        let number = if runtime_prefix {
            text.trim().strip_prefix("runtime ")
        } else {
            Some(text.trim())
        };
        number.is_some_and(|n| n.trim().parse::<f64>().is_ok_and(f64::is_finite))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mbs_core::formats::pfm::read_pfm_grey;
    use mbs_core::formats::png16::read_gray16;
    use std::io::Read;

    fn map() -> FloatImage {
        FloatImage::from_raw(3, 2, vec![1.0, 2.5, f32::INFINITY, 0.25, 100.0, 255.99]).unwrap()
    }

    /// The names and contents of a zip archive's entries, in order.
    fn unzip(path: &Path) -> Vec<(String, Vec<u8>)> {
        let mut archive = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
        (0..archive.len())
            .map(|i| {
                let mut entry = archive.by_index(i).unwrap();
                let mut bytes = Vec::new();
                entry.read_to_end(&mut bytes).unwrap();
                (entry.name().unwrap().to_string(), bytes)
            })
            .collect()
    }

    #[test]
    fn kitti_writes_16_bit_codes_and_zips_disp_0() {
        let dir = tempfile::tempdir().unwrap();
        let layout = SubmissionLayout::Kitti(KittiVersion::Kitti2015);
        for id in ["000000_10", "000001_10"] {
            assert!(!layout.is_written(dir.path(), id));
            layout.write(dir.path(), id, &map(), 0.5).unwrap();
            assert!(layout.is_written(dir.path(), id));
        }
        let codes = read_gray16(&dir.path().join("disp_0/000000_10.png")).unwrap();
        // disparity × 256, rounded; no prediction is 0.
        assert_eq!(codes.as_raw(), &[256, 640, 0, 64, 25600, 65533]);
        let ids = ["000000_10".to_string(), "000001_10".to_string()];
        let zip = layout.archive(dir.path(), &ids, &|_| true).unwrap();
        assert_eq!(zip, dir.path().join("kitti_submission.zip"));
        let entries = unzip(&zip);
        let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["disp_0/000000_10.png", "disp_0/000001_10.png"]);
        assert_eq!(
            entries[0].1,
            std::fs::read(dir.path().join("disp_0/000000_10.png")).unwrap()
        );
    }

    #[test]
    fn middlebury_and_eth3d_write_pfm_and_their_timing_files() {
        let dir = tempfile::tempdir().unwrap();
        let middlebury = SubmissionLayout::middlebury("MBS", "testH", false).unwrap();
        middlebury
            .write(dir.path(), "Australia", &map(), 1.25)
            .unwrap();
        let scene = dir.path().join("testH/Australia");
        let disparity = read_pfm_grey(&scene.join("disp0MBS.pfm")).unwrap();
        assert_eq!(disparity.as_raw(), map().as_raw());
        assert_eq!(
            std::fs::read_to_string(scene.join("timeMBS.txt")).unwrap(),
            "1.250000\n"
        );
        let eth3d = SubmissionLayout::Eth3d;
        eth3d
            .write(dir.path(), "lakeside_1l", &map(), 0.03)
            .unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.path().join("low_res_two_view/lakeside_1l.txt")).unwrap(),
            "runtime 0.030000\n"
        );
        let zip = eth3d
            .archive(dir.path(), &["lakeside_1l".to_string()], &|_| true)
            .unwrap();
        let names: Vec<String> = unzip(&zip).into_iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            [
                "low_res_two_view/lakeside_1l.pfm",
                "low_res_two_view/lakeside_1l.txt"
            ]
        );
        let err = eth3d
            .archive(dir.path(), &["missing".to_string()], &|_| true)
            .unwrap_err()
            .to_string();
        assert!(err.contains("low_res_two_view/missing.pfm"), "{err}");
    }

    #[test]
    fn middlebury_method_names_are_letters_and_digits_and_not_the_ground_truth() {
        assert!(SubmissionLayout::middlebury("S3RAFT2", "testF", false).is_ok());
        let err = SubmissionLayout::middlebury("my method", "testF", false).unwrap_err();
        assert!(err.contains("letters and digits"), "{err}");
        assert!(SubmissionLayout::middlebury("", "testF", false).is_err());
        for name in ["GT", "gt", "Gt"] {
            let err = SubmissionLayout::middlebury(name, "trainingQ", false).unwrap_err();
            assert!(err.contains("ground truth"), "{err}");
        }
    }

    /// KITTI 2012's devkit reads `<frame>.png` from the unpacked archive's
    /// root; 2015's from `disp_0/`.
    #[test]
    fn kitti_2012_archives_its_maps_at_the_root() {
        let dir = tempfile::tempdir().unwrap();
        let layout = SubmissionLayout::Kitti(KittiVersion::Kitti2012);
        layout.write(dir.path(), "000000_10", &map(), 0.5).unwrap();
        assert!(dir.path().join("000000_10.png").is_file());
        let zip = layout
            .archive(dir.path(), &["000000_10".to_string()], &|_| true)
            .unwrap();
        let names: Vec<String> = unzip(&zip).into_iter().map(|(n, _)| n).collect();
        assert_eq!(names, ["000000_10.png"]);
    }

    /// Runs over testH and then trainingH into one folder make one archive
    /// holding both splits; a sparse map takes the `_s` name.
    #[test]
    fn middlebury_archives_every_split_of_the_method() {
        let dir = tempfile::tempdir().unwrap();
        let test = SubmissionLayout::middlebury("MBS", "testH", false).unwrap();
        test.write(dir.path(), "Australia", &map(), 1.0).unwrap();
        // Another method's scene and an unfinished one are left out.
        let other = SubmissionLayout::middlebury("Other", "testH", false).unwrap();
        other.write(dir.path(), "Bicycle2", &map(), 1.0).unwrap();
        let training = SubmissionLayout::middlebury("MBS", "trainingH", false).unwrap();
        training
            .write(dir.path(), "Adirondack", &map(), 2.0)
            .unwrap();
        training
            .write(dir.path(), "Jadeplant", &map(), 2.0)
            .unwrap();
        std::fs::remove_file(dir.path().join("trainingH/Jadeplant/timeMBS.txt")).unwrap();
        // Another resolution and a backup copy are not this upload's.
        for split in ["testQ", "backup"] {
            let layout = SubmissionLayout::middlebury("MBS", split, false).unwrap();
            layout.write(dir.path(), "Australia", &map(), 1.0).unwrap();
        }
        let zip = training
            .archive(dir.path(), &["Adirondack".to_string()], &|_| true)
            .unwrap();
        let names: Vec<String> = unzip(&zip).into_iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            [
                "trainingH/Adirondack/disp0MBS.pfm",
                "trainingH/Adirondack/timeMBS.txt",
                "testH/Australia/disp0MBS.pfm",
                "testH/Australia/timeMBS.txt",
            ]
        );
        let sparse = SubmissionLayout::middlebury("MBS", "testH", true).unwrap();
        assert_eq!(
            sparse.files("Australia")[0],
            Path::new("testH/Australia/disp0MBS_s.pfm")
        );
    }

    /// A file cut short (a crash outside the atomic writer, a copy that
    /// stopped) or a timing file without a number is not counted as done.
    #[test]
    fn an_incomplete_file_is_not_written() {
        let dir = tempfile::tempdir().unwrap();
        let layout = SubmissionLayout::Eth3d;
        layout
            .write(dir.path(), "delivery_area_1l", &map(), 0.5)
            .unwrap();
        assert!(layout.is_written(dir.path(), "delivery_area_1l"));
        let pfm = dir.path().join("low_res_two_view/delivery_area_1l.pfm");
        let bytes = std::fs::read(&pfm).unwrap();
        std::fs::write(&pfm, &bytes[..bytes.len() - 3]).unwrap();
        assert!(!layout.is_written(dir.path(), "delivery_area_1l"));
        std::fs::write(&pfm, &bytes).unwrap();
        let txt = dir.path().join("low_res_two_view/delivery_area_1l.txt");
        std::fs::write(&txt, "runtime \n").unwrap();
        assert!(!layout.is_written(dir.path(), "delivery_area_1l"));
        // Each server's own form: ETH3D's "runtime N", Middlebury's "N".
        std::fs::write(&txt, "0.5\n").unwrap();
        assert!(!layout.is_written(dir.path(), "delivery_area_1l"));
        let middlebury = SubmissionLayout::middlebury("MBS", "testH", false).unwrap();
        middlebury
            .write(dir.path(), "Australia", &map(), 0.5)
            .unwrap();
        assert!(middlebury.is_written(dir.path(), "Australia"));
        let time = dir.path().join("testH/Australia/timeMBS.txt");
        std::fs::write(&time, "runtime 0.5\n").unwrap();
        assert!(!middlebury.is_written(dir.path(), "Australia"));
        let kitti = SubmissionLayout::Kitti(KittiVersion::Kitti2015);
        kitti.write(dir.path(), "000000_10", &map(), 0.5).unwrap();
        let png = dir.path().join("disp_0/000000_10.png");
        let bytes = std::fs::read(&png).unwrap();
        std::fs::write(&png, &bytes[..bytes.len() - 20]).unwrap();
        assert!(!kitti.is_written(dir.path(), "000000_10"));
    }
}
