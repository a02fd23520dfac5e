//! Token buckets for citizens' writes (comments, likes, reports): one bucket per author token
//! and one per client address, so that neither one browser nor one machine can flood a
//! participation. A refused write is a 429 with `Retry-After`.

use crate::scene::participation::RateLimit;
use std::collections::HashMap;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Buckets kept before idle ones (full again) are forgotten.
const MAX_BUCKETS: usize = 10_000;

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    at: Instant,
}

impl Bucket {
    /// The bucket refilled up to `now`.
    fn refilled(self, limit: RateLimit, now: Instant) -> Bucket {
        let gained = now.saturating_duration_since(self.at).as_secs_f64() * limit.per_minute / 60.0;
        Bucket { tokens: (self.tokens + gained).min(f64::from(limit.burst)), at: now }
    }
}

/// The buckets of one kind of key (author tokens or addresses).
#[derive(Debug)]
pub struct RateLimiter {
    limit: RateLimit,
    buckets: Mutex<HashMap<String, Bucket>>,
}

impl RateLimiter {
    /// Buckets of `limit.burst` actions refilled at `limit.per_minute`.
    pub fn new(limit: RateLimit) -> RateLimiter {
        RateLimiter { limit, buckets: Mutex::new(HashMap::new()) }
    }

    /// Whether `key` may act now (taking one action); `Err(wait)` with the time until it may.
    pub fn check(&self, key: &str, now: Instant) -> Result<(), Duration> {
        take(&[(self, key)], now)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Bucket>> {
        self.buckets.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn current(&self, key: &str, now: Instant) -> Bucket {
        let full = Bucket { tokens: f64::from(self.limit.burst), at: now };
        self.lock().get(key).map_or(full, |b| b.refilled(self.limit, now))
    }

    fn store(&self, key: &str, bucket: Bucket) {
        let mut buckets = self.lock();
        if buckets.len() >= MAX_BUCKETS {
            let (limit, now) = (self.limit, bucket.at);
            buckets.retain(|_, b| b.refilled(limit, now).tokens < f64::from(limit.burst));
        }
        buckets.insert(key.to_owned(), bucket);
    }
}

/// Takes one action from each `(limiter, key)` if every bucket has one, else none (a refused
/// action costs nothing); `Err(wait)`: the longest time until all have one.
pub fn take(keys: &[(&RateLimiter, &str)], now: Instant) -> Result<(), Duration> {
    let mut wait = Duration::ZERO;
    for (limiter, key) in keys {
        let bucket = limiter.current(key, now);
        if bucket.tokens < 1.0 {
            let seconds = (1.0 - bucket.tokens) * 60.0 / limiter.limit.per_minute;
            wait = wait.max(Duration::from_secs_f64(seconds));
        }
    }
    if wait > Duration::ZERO {
        return Err(wait);
    }
    for (limiter, key) in keys {
        let bucket = limiter.current(key, now);
        limiter.store(key, Bucket { tokens: bucket.tokens - 1.0, ..bucket });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bucket_allows_its_burst_then_refills_at_its_rate() {
        let limiter = RateLimiter::new(RateLimit { burst: 3, per_minute: 6.0 });
        let t0 = Instant::now();
        for _ in 0..3 {
            assert_eq!(limiter.check("a", t0), Ok(()));
        }
        let wait = limiter.check("a", t0).expect_err("burst used up");
        assert!((wait.as_secs_f64() - 10.0).abs() < 1e-6, "{wait:?}");
        assert_eq!(limiter.check("b", t0), Ok(()), "other keys have their own bucket");
        assert!(limiter.check("a", t0 + Duration::from_secs(9)).is_err());
        assert_eq!(limiter.check("a", t0 + Duration::from_secs(10)), Ok(()));
    }

    #[test]
    fn a_refusal_by_one_bucket_costs_the_other_nothing() {
        let tokens = RateLimiter::new(RateLimit { burst: 1, per_minute: 1.0 });
        let addresses = RateLimiter::new(RateLimit { burst: 2, per_minute: 1.0 });
        let t0 = Instant::now();
        assert_eq!(take(&[(&tokens, "t"), (&addresses, "ip")], t0), Ok(()));
        assert!(take(&[(&tokens, "t"), (&addresses, "ip")], t0).is_err());
        // The address bucket still has its second action.
        assert_eq!(addresses.check("ip", t0), Ok(()));
        assert!(addresses.check("ip", t0).is_err());
    }
}
