//! Walking a dataset's folders as users lay them out: symbolic links are
//! followed (a town or a pass behind a link is part of the dataset), a
//! link back to a folder above is walked once (by the folder's own path),
//! and entries come in path order.

use std::path::Path;

use crate::DatasetError;

/// Every entry under `root` (itself included), in path order, links
/// followed; an entry that cannot be read is an error naming it.
pub(crate) fn entries(
    root: &Path,
) -> impl Iterator<Item = Result<walkdir::DirEntry, DatasetError>> + '_ {
    walkdir::WalkDir::new(root)
        .follow_links(true)
        .sort_by_file_name()
        .into_iter()
        .filter_map(move |entry| match entry {
            Ok(entry) => Some(Ok(entry)),
            // Everything under a link to a folder above is reached by the
            // folder's own path.
            Err(e) if e.loop_ancestor().is_some() => None,
            Err(e) => Some(Err(DatasetError::Io {
                path: e.path().unwrap_or(root).to_path_buf(),
                source: e.into(),
            })),
        })
}
