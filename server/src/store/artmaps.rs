//! Uploaded art maps in the data directory, so that they survive restarts:
//!
//! ```text
//! <dir>/artmaps/<kind>-<index>.png   the PNG as uploaded (kind `tam` or `sam`)
//! ```
//!
//! Writes are atomic like the layers' (a temporary file in the same directory, `fsync`,
//! rename); temporary files left by a crash are removed when the maps are listed.

use super::{Store, StoreError, io_err, sync_dir};
use crate::render::art_textures::ArtKind;
use std::fs;
use std::io::ErrorKind;
use std::path::PathBuf;
use tracing::warn;

/// An uploaded art map stored in the data directory.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoredArtMap {
    /// TAM or SAM.
    pub kind: ArtKind,
    /// The index it replaces or was added as.
    pub index: usize,
    /// The PNG file.
    pub path: PathBuf,
}

impl Store {
    fn art_maps_dir(&self) -> PathBuf {
        self.root.join("artmaps")
    }

    fn art_map_path(&self, kind: ArtKind, index: usize) -> PathBuf {
        self.art_maps_dir().join(format!("{}-{index}.png", kind.name()))
    }

    /// Stores the PNG of uploaded art map `index` of `kind`, replacing an earlier one
    /// atomically.
    pub fn save_art_map(&self, kind: ArtKind, index: usize, png: &[u8]) -> Result<(), StoreError> {
        let dir = self.art_maps_dir();
        fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        self.write_file_atomic(&self.art_map_path(kind, index), png)?;
        sync_dir(&dir)
    }

    /// Removes the stored art map `index` of `kind`; a map that was never stored is no error.
    pub fn delete_art_map(&self, kind: ArtKind, index: usize) -> Result<(), StoreError> {
        let path = self.art_map_path(kind, index);
        match fs::remove_file(&path) {
            Ok(()) => sync_dir(&self.art_maps_dir()),
            Err(e) if e.kind() == ErrorKind::NotFound => Ok(()),
            Err(e) => Err(io_err(&path)(e)),
        }
    }

    /// The stored art maps, TAMs before SAMs, each kind by index; removes temporary files a
    /// crash left behind and skips (with a warning) files of other names.
    pub fn art_maps(&self) -> Result<Vec<StoredArtMap>, StoreError> {
        let dir = self.art_maps_dir();
        let entries = match fs::read_dir(&dir) {
            Ok(entries) => entries,
            Err(e) if e.kind() == ErrorKind::NotFound => return Ok(Vec::new()),
            Err(e) => return Err(io_err(&dir)(e)),
        };
        let mut found = Vec::new();
        for entry in entries {
            let path = entry.map_err(io_err(&dir))?.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            match parse_file_name(name) {
                Some((kind, index)) => found.push(StoredArtMap { kind, index, path }),
                None if name.starts_with('.') && name.contains(".tmp-") => {
                    if let Err(e) = fs::remove_file(&path) {
                        warn!(path = %path.display(), error = %e, "cannot remove a leftover temporary art map");
                    }
                }
                None => warn!(path = %path.display(), "ignoring a file that is no stored art map"),
            }
        }
        found.sort_by_key(|m| (m.kind, m.index));
        Ok(found)
    }
}

/// `tam-3.png` → (TAM, 3); other names (`tam-03.png`, `tam-+3.png`, `x-1.png`) → `None`.
fn parse_file_name(name: &str) -> Option<(ArtKind, usize)> {
    let (kind, index) = name.strip_suffix(".png")?.split_once('-')?;
    let number: usize = index.parse().ok()?;
    (number.to_string() == index).then_some((ArtKind::from_name(kind)?, number))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_names_round_trip_and_others_are_refused() {
        assert_eq!(parse_file_name("tam-3.png"), Some((ArtKind::Tam, 3)));
        assert_eq!(parse_file_name("sam-0.png"), Some((ArtKind::Sam, 0)));
        for name in ["tam-03.png", "tam-+3.png", "tam-3", "x-1.png", ".tam-1.png.tmp-0a", "tam--1.png"] {
            assert_eq!(parse_file_name(name), None, "{name}");
        }
    }

    #[test]
    fn saved_maps_are_listed_replaced_and_deleted() {
        let dir = tempfile::tempdir().expect("temp dir");
        let store = Store::open(dir.path()).expect("store");
        assert_eq!(store.art_maps().expect("list").len(), 0, "no directory yet");
        store.save_art_map(ArtKind::Sam, 1, b"one").expect("save");
        store.save_art_map(ArtKind::Tam, 4, b"two").expect("save");
        store.save_art_map(ArtKind::Sam, 1, b"three").expect("replace");
        fs::write(dir.path().join("artmaps/.tam-4.png.tmp-0123"), b"half").expect("leftover");
        let listed = store.art_maps().expect("list");
        let keys: Vec<_> = listed.iter().map(|m| (m.kind, m.index)).collect();
        assert_eq!(keys, [(ArtKind::Tam, 4), (ArtKind::Sam, 1)]);
        assert_eq!(fs::read(&listed[1].path).expect("read"), b"three");
        assert!(!dir.path().join("artmaps/.tam-4.png.tmp-0123").exists(), "leftover removed");
        store.delete_art_map(ArtKind::Tam, 4).expect("delete");
        store.delete_art_map(ArtKind::Tam, 4).expect("deleting again is no error");
        assert_eq!(store.art_maps().expect("list").len(), 1);
    }
}
