//! Single photos as a command's input (`mbs-tool mono`): one file, a
//! folder walked in path order, a list file, or one camera's views of a
//! manifest; each photo gets an id, the confined name its outputs are
//! written under.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::manifest::{Manifest, Split, resolve};
use crate::walk::entries;
use crate::{DatasetError, utf8_file_name};

/// The extensions a folder's photos are found by (lower case).
pub const PHOTO_EXTENSIONS: [&str; 6] = ["png", "jpg", "jpeg", "ppm", "pgm", "pnm"];

/// One photo and the id its outputs are named by.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Photo {
    /// The image file.
    pub path: PathBuf,
    /// A confined name (see [`mbs_core::confine`]): the file stem, the
    /// path under a folder without its extension, or a manifest sample's id.
    pub id: String,
}

/// Where the photos come from.
#[derive(Debug, Clone, PartialEq)]
pub enum PhotoSource {
    /// One image file; its id is its stem.
    File(PathBuf),
    /// Every image under a folder (by [`PHOTO_EXTENSIONS`], links
    /// followed, in path order) but those under `skip` (the output
    /// folder); ids are the paths under the folder without extension.
    Folder {
        /// The folder.
        dir: PathBuf,
        /// A folder inside it whose files are not inputs.
        skip: Option<PathBuf>,
    },
    /// A list file of image paths, relative to the list's folder; ids as
    /// for a folder, relative to the list's folder.
    List(PathBuf),
    /// View `camera` of every sample of a manifest (of `split` only, when
    /// given); ids are the samples' ids.
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// The camera whose views are the photos.
        camera: usize,
        /// Only samples of this split.
        split: Option<Split>,
    },
}

impl PhotoSource {
    /// The photos, in order. Two photos with one id (`a.png` and `a.jpg`),
    /// an id that is not a confined name, a missing file, an empty source
    /// or a camera a sample lacks is an error naming the file.
    pub fn photos(&self) -> Result<Vec<Photo>, DatasetError> {
        let photos = match self {
            PhotoSource::File(path) => vec![Photo {
                id: stem(path)?,
                path: path.clone(),
            }],
            PhotoSource::Folder { dir, skip } => folder_photos(dir, skip.as_deref())?,
            PhotoSource::List(list) => list_photos(list)?,
            PhotoSource::Manifest {
                path,
                camera,
                split,
            } => manifest_photos(path, *camera, *split)?,
        };
        check_ids(self.origin(), &photos)?;
        Ok(photos)
    }

    /// The file or folder the photos are named in (what errors point at).
    fn origin(&self) -> &Path {
        match self {
            PhotoSource::File(path) | PhotoSource::List(path) => path,
            PhotoSource::Folder { dir, .. } => dir,
            PhotoSource::Manifest { path, .. } => path,
        }
    }
}

fn layout(path: &Path, message: impl Into<String>) -> DatasetError {
    DatasetError::Layout {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// The file stem of `path`, as text.
fn stem(path: &Path) -> Result<String, DatasetError> {
    let name = utf8_file_name(path)?;
    Ok(Path::new(name)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(name)
        .to_string())
}

/// `path` under `root` without its extension, `/`-separated.
fn id_under(root: &Path, path: &Path) -> Result<String, DatasetError> {
    let relative = path.strip_prefix(root).unwrap_or(path);
    let mut segments: Vec<String> = relative
        .parent()
        .into_iter()
        .flat_map(Path::components)
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    segments.push(stem(path)?);
    Ok(segments.join("/"))
}

fn is_photo(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| PHOTO_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

fn folder_photos(dir: &Path, skip: Option<&Path>) -> Result<Vec<Photo>, DatasetError> {
    if !dir.is_dir() {
        return Err(layout(dir, "no such folder"));
    }
    let skip = skip.and_then(|s| std::fs::canonicalize(s).ok());
    let mut photos = Vec::new();
    for entry in entries(dir) {
        let entry = entry?;
        let path = entry.path();
        let skipped = skip
            .as_ref()
            .is_some_and(|s| std::fs::canonicalize(path).is_ok_and(|p| p.starts_with(s)));
        if entry.file_type().is_file() && is_photo(path) && !skipped {
            photos.push(Photo {
                id: id_under(dir, path)?,
                path: path.to_path_buf(),
            });
        }
    }
    if photos.is_empty() {
        return Err(layout(
            dir,
            format!(
                "no image in this folder (looked for .{})",
                PHOTO_EXTENSIONS.join(", .")
            ),
        ));
    }
    Ok(photos)
}

fn list_photos(list: &Path) -> Result<Vec<Photo>, DatasetError> {
    let text = mbs_core::regular::read_text(list)?;
    let root = list.parent().unwrap_or(Path::new(""));
    let photos = mbs_core::list_file::list_entries(&text)
        .into_iter()
        .map(|entry| {
            let path = root.join(&entry);
            if !path.is_file() {
                return Err(layout(list, format!("lists {entry}, which is not a file")));
            }
            Ok(Photo {
                id: id_under(root, &path)?,
                path,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    if photos.is_empty() {
        return Err(layout(list, "the list names no image"));
    }
    Ok(photos)
}

fn manifest_photos(
    path: &Path,
    camera: usize,
    split: Option<Split>,
) -> Result<Vec<Photo>, DatasetError> {
    let manifest = Manifest::load(path)?;
    let photos = manifest
        .samples
        .iter()
        .filter(|sample| split.is_none_or(|s| sample.split == s))
        .map(|sample| {
            let view = sample.views.get(camera).ok_or_else(|| {
                layout(
                    path,
                    format!(
                        "sample {} has {} views; there is no camera {camera}",
                        sample.id,
                        sample.views.len()
                    ),
                )
            })?;
            Ok::<_, DatasetError>(Photo {
                path: resolve(path, view),
                id: sample.id.clone(),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    if photos.is_empty() {
        return Err(layout(path, "no sample of the split asked for"));
    }
    Ok(photos)
}

/// Refuses ids that are not confined names, and two photos with one id.
fn check_ids(origin: &Path, photos: &[Photo]) -> Result<(), DatasetError> {
    let mut seen: BTreeMap<&str, &Path> = BTreeMap::new();
    for photo in photos {
        mbs_core::confine::check_name(&photo.id).map_err(|why| {
            layout(
                &photo.path,
                format!("its id {:?} {why}; rename the file", photo.id),
            )
        })?;
        if let Some(first) = seen.insert(&photo.id, &photo.path) {
            return Err(layout(
                origin,
                format!(
                    "{} and {} would both be written as {:?}: rename one",
                    first.display(),
                    photo.path.display(),
                    photo.id
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(path: &Path) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, b"x").unwrap();
    }

    #[test]
    fn folders_and_lists_give_ids_by_relative_path() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path();
        for name in ["b.JPG", "a.png", "sub/c.jpeg", "notes.txt", "out/x.png"] {
            touch(&root.join(name));
        }
        let source = PhotoSource::Folder {
            dir: root.to_path_buf(),
            skip: Some(root.join("out")),
        };
        let ids: Vec<String> = source.photos().unwrap().into_iter().map(|p| p.id).collect();
        assert_eq!(ids, ["a", "b", "sub/c"]);
        let list = root.join("list.txt");
        std::fs::write(&list, "# photos\nsub/c.jpeg\na.png\n").unwrap();
        let photos = PhotoSource::List(list.clone()).photos().unwrap();
        assert_eq!(photos[0].id, "sub/c");
        assert_eq!(photos[1].path, root.join("a.png"));
        std::fs::write(&list, "a.png\nmissing.png\n").unwrap();
        let err = PhotoSource::List(list).photos().unwrap_err().to_string();
        assert!(
            err.contains("list.txt: lists missing.png, which is not a file"),
            "{err}"
        );
    }

    #[test]
    fn two_photos_with_one_id_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        touch(&dir.path().join("a.png"));
        touch(&dir.path().join("a.jpg"));
        let source = PhotoSource::Folder {
            dir: dir.path().to_path_buf(),
            skip: None,
        };
        let err = source.photos().unwrap_err().to_string();
        assert!(
            err.contains("would both be written as \"a\": rename one"),
            "{err}"
        );
        let empty = tempfile::tempdir().unwrap();
        let err = PhotoSource::Folder {
            dir: empty.path().to_path_buf(),
            skip: None,
        }
        .photos()
        .unwrap_err()
        .to_string();
        assert!(err.contains("no image in this folder"), "{err}");
    }
}
