//! The files the benchmarks' evaluation servers accept, written as their
//! documentation lays them out, with the time each prediction took:
//!
//! - KITTI 2012 and 2015: `disp_0/<frame>.png`, 16-bit, disparity × 256
//!   rounded, 0 = no prediction; zipped as `kitti_submission.zip` with
//!   `disp_0/` at its root (the server takes no timing file: the time is
//!   entered in its form).
//! - Middlebury MiddEval3: `<split>/<Scene>/disp0<NAME>.pfm` (float PFM,
//!   `inf` = no prediction) and `time<NAME>.txt` (seconds), the split
//!   folder named as the input's (`testH`, `trainingH`, …); zipped as
//!   `middlebury_submission.zip`.
//! - ETH3D two-view: `low_res_two_view/<scene>.pfm` and `<scene>.txt`
//!   holding `runtime <seconds>`; zipped as `eth3d_submission.zip`.
//!
//! Every file is written atomically; the archive is made last from the
//! files present, so a resumed run's archive holds every pair.

use std::io::Write;
use std::path::{Path, PathBuf};

use mbs_core::FloatImage;
use mbs_core::atomic::{write_atomic, write_bytes_atomic};
use mbs_core::formats::pfm::{Endian, write_pfm_grey};
use mbs_core::formats::png16::write_kitti_disparity;

use crate::DatasetError;

/// A benchmark server's submission layout.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SubmissionLayout {
    /// KITTI 2012 or 2015 stereo.
    Kitti,
    /// Middlebury MiddEval3: the method's name (letters and digits, as
    /// the files are named after it) and the split folder's name.
    Middlebury {
        /// The method's name in the file names.
        method: String,
        /// The split folder, e.g. `testH`.
        split: String,
    },
    /// ETH3D two-view (low resolution).
    Eth3d,
}

impl SubmissionLayout {
    /// Middlebury's layout for `method` and the split folder `split`; a
    /// name with anything but ASCII letters and digits is refused, since
    /// MiddEval3's scripts read it back from the file names.
    pub fn middlebury(method: &str, split: &str) -> Result<Self, String> {
        if method.is_empty() || !method.chars().all(|c| c.is_ascii_alphanumeric()) {
            return Err(format!(
                "`{method}` cannot name a Middlebury method: use letters and digits only \
                 (it becomes disp0{method}.pfm)"
            ));
        }
        Ok(SubmissionLayout::Middlebury {
            method: method.to_string(),
            split: split.to_string(),
        })
    }

    /// The files of pair `id`, relative to the submission folder: the
    /// disparity first, then its timing file where the layout has one.
    pub fn files(&self, id: &str) -> Vec<PathBuf> {
        match self {
            SubmissionLayout::Kitti => vec![Path::new("disp_0").join(format!("{id}.png"))],
            SubmissionLayout::Middlebury { method, split } => {
                let scene = Path::new(split).join(id);
                vec![
                    scene.join(format!("disp0{method}.pfm")),
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

    /// Whether every file of pair `id` is in `out` (a resumed run skips it).
    pub fn is_written(&self, out: &Path, id: &str) -> bool {
        self.files(id).iter().all(|f| out.join(f).is_file())
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
            SubmissionLayout::Kitti => write_kitti_disparity(&files[0], disparity)?,
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

    /// The archive's file name.
    pub fn archive_name(&self) -> &'static str {
        match self {
            SubmissionLayout::Kitti => "kitti_submission.zip",
            SubmissionLayout::Middlebury { .. } => "middlebury_submission.zip",
            SubmissionLayout::Eth3d => "eth3d_submission.zip",
        }
    }

    /// Zips the files of pairs `ids` found under `out` into `out`'s
    /// archive (paths relative to `out`, `/`-separated, in `ids`' order);
    /// returns its path. A pair whose files are missing is an error naming
    /// the file.
    pub fn archive(&self, out: &Path, ids: &[String]) -> Result<PathBuf, DatasetError> {
        let path = out.join(self.archive_name());
        let mut entries = Vec::new();
        for id in ids {
            for file in self.files(id) {
                let bytes = std::fs::read(out.join(&file)).map_err(|source| DatasetError::Io {
                    path: out.join(&file),
                    source,
                })?;
                let name = file
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join("/");
                entries.push((name, bytes));
            }
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
        let layout = SubmissionLayout::Kitti;
        for id in ["000000_10", "000001_10"] {
            assert!(!layout.is_written(dir.path(), id));
            layout.write(dir.path(), id, &map(), 0.5).unwrap();
            assert!(layout.is_written(dir.path(), id));
        }
        let codes = read_gray16(&dir.path().join("disp_0/000000_10.png")).unwrap();
        // disparity × 256, rounded; no prediction is 0.
        assert_eq!(codes.as_raw(), &[256, 640, 0, 64, 25600, 65533]);
        let ids = ["000000_10".to_string(), "000001_10".to_string()];
        let zip = layout.archive(dir.path(), &ids).unwrap();
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
        let middlebury = SubmissionLayout::middlebury("MBS", "testH").unwrap();
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
            .archive(dir.path(), &["lakeside_1l".to_string()])
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
            .archive(dir.path(), &["missing".to_string()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("low_res_two_view/missing.pfm"), "{err}");
    }

    #[test]
    fn middlebury_method_names_are_letters_and_digits() {
        assert!(SubmissionLayout::middlebury("S3RAFT2", "testF").is_ok());
        let err = SubmissionLayout::middlebury("my method", "testF").unwrap_err();
        assert!(err.contains("letters and digits"), "{err}");
        assert!(SubmissionLayout::middlebury("", "testF").is_err());
    }
}
