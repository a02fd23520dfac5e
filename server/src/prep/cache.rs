//! A content-addressed disk cache for preprocessing results (HLP clusterings, baked billboard
//! atlases), so a restart with the same scene does no preprocessing.
//!
//! Layout: `<dir>/<kind>/<sha256 of key>.bin`. Entries are written to a temporary file and
//! renamed into place, so a crash never leaves a half entry; an unreadable or corrupt entry is
//! recomputed. Failing to write the cache is logged and otherwise ignored: the cache only ever
//! saves time.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use tracing::{debug, warn};

/// The disk cache of one process.
#[derive(Debug)]
pub struct DiskCache {
    dir: PathBuf,
    hits: AtomicU64,
    misses: AtomicU64,
}

/// How often the cache answered from disk and how often it had to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CacheStats {
    pub hits: u64,
    pub misses: u64,
}

/// Builds a cache key from the parts that decide a result (content hashes, parameters, and
/// the version of the algorithm that produced it).
#[derive(Default)]
pub struct KeyBuilder(Sha256);

impl KeyBuilder {
    /// Adds raw bytes to the key.
    pub fn bytes(mut self, bytes: &[u8]) -> Self {
        self.0.update((bytes.len() as u64).to_le_bytes());
        self.0.update(bytes);
        self
    }

    /// Adds a number to the key.
    pub fn u64(self, value: u64) -> Self {
        self.bytes(&value.to_le_bytes())
    }

    /// Adds a float to the key (by its bits).
    pub fn f32(self, value: f32) -> Self {
        self.bytes(&value.to_bits().to_le_bytes())
    }

    /// The key as a hex string, usable as a file name.
    pub fn finish(self) -> String {
        self.0.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }
}

impl DiskCache {
    /// Opens (creating if needed) a cache in `dir`.
    pub fn open(dir: impl Into<PathBuf>) -> std::io::Result<DiskCache> {
        let dir = dir.into();
        std::fs::create_dir_all(&dir)?;
        Ok(DiskCache { dir, hits: AtomicU64::new(0), misses: AtomicU64::new(0) })
    }

    /// The cache directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Hit and miss counts since the cache was opened.
    pub fn stats(&self) -> CacheStats {
        CacheStats { hits: self.hits.load(Ordering::Relaxed), misses: self.misses.load(Ordering::Relaxed) }
    }

    fn path(&self, kind: &str, key: &str) -> PathBuf {
        self.dir.join(kind).join(format!("{key}.bin"))
    }

    /// Returns the entry `kind`/`key` decoded by `decode`, or computes it with `compute`,
    /// stores `encode(&value)` and returns it. An entry that fails to decode is recomputed.
    pub fn get_or_compute<T>(
        &self,
        kind: &str,
        key: &str,
        decode: impl FnOnce(&[u8]) -> Option<T>,
        encode: impl FnOnce(&T) -> Vec<u8>,
        compute: impl FnOnce() -> T,
    ) -> T {
        let path = self.path(kind, key);
        if let Ok(bytes) = std::fs::read(&path) {
            if let Some(value) = decode(&bytes) {
                self.hits.fetch_add(1, Ordering::Relaxed);
                debug!(kind, key, "preprocessing cache hit");
                return value;
            }
            warn!(path = %path.display(), "corrupt preprocessing cache entry; recomputing");
        }
        self.misses.fetch_add(1, Ordering::Relaxed);
        let value = compute();
        if let Err(error) = write_atomic(&path, &encode(&value)) {
            warn!(path = %path.display(), %error, "cannot write the preprocessing cache");
        }
        value
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let tmp = dir.join(format!(".tmp-{}-{:?}", std::process::id(), std::thread::current().id()));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

/// Little-endian reader over a cache entry, for the decoders of cached values.
pub struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    /// Starts reading at the beginning of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader(bytes)
    }

    /// Reads `n` raw bytes.
    pub fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if self.0.len() < n {
            return None;
        }
        let (head, tail) = self.0.split_at(n);
        self.0 = tail;
        Some(head)
    }

    /// Reads a `u32`.
    pub fn u32(&mut self) -> Option<u32> {
        self.take(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Reads an `f32`.
    pub fn f32(&mut self) -> Option<f32> {
        self.u32().map(f32::from_bits)
    }

    /// True when everything has been read.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_lookup_is_a_hit_and_corrupt_entries_are_recomputed() {
        let dir = tempfile::tempdir().unwrap();
        let cache = DiskCache::open(dir.path()).unwrap();
        let key = KeyBuilder::default().u64(7).f32(0.5).finish();
        let decode = |b: &[u8]| Reader::new(b).u32();
        let encode = |v: &u32| v.to_le_bytes().to_vec();
        assert_eq!(cache.get_or_compute("t", &key, decode, encode, || 42), 42);
        assert_eq!(cache.get_or_compute("t", &key, decode, encode, || unreachable!()), 42);
        assert_eq!(cache.stats(), CacheStats { hits: 1, misses: 1 });
        // A reopened cache (a restart) still hits.
        let reopened = DiskCache::open(dir.path()).unwrap();
        assert_eq!(reopened.get_or_compute("t", &key, decode, encode, || 0), 42);
        assert_eq!(reopened.stats().hits, 1);
        // A truncated entry is recomputed.
        std::fs::write(reopened.path("t", &key), [1u8]).unwrap();
        assert_eq!(reopened.get_or_compute("t", &key, decode, encode, || 43), 43);
        assert_eq!(reopened.stats().misses, 1);
        // Different parameters give different keys.
        assert_ne!(key, KeyBuilder::default().u64(7).f32(0.25).finish());
    }
}
