//! A byte-bounded LRU cache of encoded images, keyed by ETag.

use super::metrics::Metrics;
use axum::body::Bytes;
use std::collections::{BTreeMap, HashMap};
use std::sync::{Mutex, PoisonError};

/// An encoded image as it is served.
#[derive(Debug, Clone)]
pub struct CachedImage {
    /// PNG or JPEG bytes.
    pub bytes: Bytes,
    /// Milliseconds the renderer took for it.
    pub render_ms: f32,
}

#[derive(Default)]
struct Lru {
    entries: HashMap<String, (CachedImage, u64)>,
    /// Last-use tick → key; the first entry is the least recently used.
    order: BTreeMap<u64, String>,
    tick: u64,
    bytes: usize,
}

/// Least-recently-used cache holding at most `capacity` bytes of images (plus keys).
pub struct RenderCache {
    lru: Mutex<Lru>,
    capacity: usize,
    metrics: Metrics,
}

fn weight(key: &str, image: &CachedImage) -> usize {
    key.len() + image.bytes.len()
}

impl RenderCache {
    /// An empty cache of `capacity` bytes (0 stores nothing) reporting to `metrics`.
    pub fn new(capacity: usize, metrics: Metrics) -> RenderCache {
        RenderCache { lru: Mutex::default(), capacity, metrics }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Lru> {
        self.lru.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The image stored under `key`, now the most recently used; counts a hit or a miss.
    pub fn get(&self, key: &str) -> Option<CachedImage> {
        let mut lru = self.lock();
        let lru = &mut *lru;
        lru.tick += 1;
        let found = lru.entries.get_mut(key).map(|(image, tick)| {
            lru.order.remove(tick);
            *tick = lru.tick;
            image.clone()
        });
        match found {
            Some(image) => {
                lru.order.insert(lru.tick, key.to_owned());
                self.metrics.cache_hits.inc();
                Some(image)
            }
            None => {
                self.metrics.cache_misses.inc();
                None
            }
        }
    }

    /// Stores `image` under `key`, evicting least recently used images to stay within the
    /// capacity; an image larger than the whole cache is not stored.
    pub fn insert(&self, key: String, image: CachedImage) {
        let size = weight(&key, &image);
        if size > self.capacity {
            return;
        }
        let mut lru = self.lock();
        let lru = &mut *lru;
        lru.tick += 1;
        if let Some((old, tick)) = lru.entries.remove(&key) {
            lru.order.remove(&tick);
            lru.bytes -= weight(&key, &old);
        }
        while lru.bytes + size > self.capacity {
            let Some((_, oldest)) = lru.order.pop_first() else { break };
            if let Some((old, _)) = lru.entries.remove(&oldest) {
                lru.bytes -= weight(&oldest, &old);
            }
        }
        lru.bytes += size;
        lru.order.insert(lru.tick, key.clone());
        lru.entries.insert(key, (image, lru.tick));
        self.report(lru);
    }

    /// Removes every image; returns how many images and bytes were dropped.
    pub fn clear(&self) -> (usize, usize) {
        let mut lru = self.lock();
        let dropped = (lru.entries.len(), lru.bytes);
        *lru = Lru::default();
        self.report(&lru);
        dropped
    }

    fn report(&self, lru: &Lru) {
        self.metrics.cache_entries.set(i64::try_from(lru.entries.len()).unwrap_or(i64::MAX));
        self.metrics.cache_bytes.set(i64::try_from(lru.bytes).unwrap_or(i64::MAX));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(size: usize) -> CachedImage {
        CachedImage { bytes: Bytes::from(vec![0; size]), render_ms: 1.0 }
    }

    #[test]
    fn evicts_least_recently_used_within_the_byte_budget() {
        let cache = RenderCache::new(300, Metrics::new());
        cache.insert("a".into(), image(99));
        cache.insert("b".into(), image(99));
        cache.insert("c".into(), image(99));
        assert!(cache.get("a").is_some()); // a is now newer than b
        cache.insert("d".into(), image(99));
        assert!(cache.get("b").is_none());
        assert!(cache.get("a").is_some() && cache.get("c").is_some() && cache.get("d").is_some());
        cache.insert("huge".into(), image(1000));
        assert!(cache.get("huge").is_none());
        assert_eq!(cache.clear(), (3, 300));
        assert!(cache.get("a").is_none());
    }

    #[test]
    fn replacing_a_key_keeps_the_byte_count() {
        let cache = RenderCache::new(1000, Metrics::new());
        cache.insert("k".into(), image(10));
        cache.insert("k".into(), image(20));
        assert_eq!(cache.clear(), (1, 21));
    }
}
