//! Which runs of a campaign this process takes, and the seed of each run.
//!
//! Contract: shard `K/M` (1 ≤ K ≤ M) takes the runs `i` with `i mod M = K − 1`, so the M shards
//! of a campaign take every run exactly once. Without `--shard`, Kubernetes' 0-based
//! `JOB_COMPLETION_INDEX` gives K = index + 1, with M from `HARVEMU_SHARDS`; with neither the
//! campaign is one shard, and `HARVEMU_SHARDS` alone is an error. A run's seed depends only on the campaign's seed and the run's number.

use std::fmt;

/// The environment variable Kubernetes sets in each pod of an Indexed Job (0-based).
pub const INDEX_VAR: &str = "JOB_COMPLETION_INDEX";
/// The environment variable that gives the shard count beside [`INDEX_VAR`].
pub const SHARDS_VAR: &str = "HARVEMU_SHARDS";

/// Shard `k` of `m`, 1-based.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 1 to `m`.
    pub k: u64,
    /// How many shards.
    pub m: u64,
}

impl Shard {
    /// The whole campaign in one shard.
    pub const ALL: Shard = Shard { k: 1, m: 1 };

    /// Reads `K/M`.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (k, m) = text
            .split_once('/')
            .ok_or_else(|| format!("{text:?} is not K/M (for example 2/4)"))?;
        let number = |s: &str, what: &str| {
            s.trim()
                .parse::<u64>()
                .map_err(|_| format!("{what} in {text:?} is not a whole number"))
        };
        Shard::new(number(k, "K")?, number(m, "M")?)
    }

    /// Shard `k` of `m`, when `1 ≤ k ≤ m`.
    pub fn new(k: u64, m: u64) -> Result<Shard, String> {
        if m == 0 {
            return Err("there must be at least one shard (M ≥ 1)".into());
        }
        if k == 0 || k > m {
            return Err(format!("shard {k}/{m}: K runs from 1 to {m}"));
        }
        Ok(Shard { k, m })
    }

    /// The shard from the environment (see the module contract): `index` and `shards` are the
    /// values of [`INDEX_VAR`] and [`SHARDS_VAR`], when set.
    pub fn from_env(index: Option<&str>, shards: Option<&str>) -> Result<Shard, String> {
        let Some(index) = index else {
            // Sharding asked for without saying which shard: taking the whole campaign would
            // run every shard's runs in every pod.
            return match shards {
                Some(m) => Err(format!(
                    "{SHARDS_VAR}={m:?} is set but {INDEX_VAR} is not: set it to this pod's                      0-based index (a Kubernetes Indexed Job does), or pass --shard K/M"
                )),
                None => Ok(Shard::ALL),
            };
        };
        let index: u64 = index
            .trim()
            .parse()
            .map_err(|_| format!("{INDEX_VAR}={index:?} is not a whole number"))?;
        let shards = shards.ok_or_else(|| {
            format!("{INDEX_VAR} is set but {SHARDS_VAR} is not: set it to the Job's completion count")
        })?;
        let m: u64 = shards
            .trim()
            .parse()
            .map_err(|_| format!("{SHARDS_VAR}={shards:?} is not a whole number"))?;
        let k = index.checked_add(1).ok_or("the index is too large")?;
        Shard::new(k, m).map_err(|e| format!("{INDEX_VAR}={index} with {SHARDS_VAR}={m}: {e}"))
    }

    /// Whether run `i` is this shard's.
    pub fn takes(self, i: u64) -> bool {
        i % self.m == self.k - 1
    }

    /// How many of the runs `0..runs` are this shard's.
    pub fn count(self, runs: u64) -> u64 {
        runs.saturating_sub(self.k - 1).div_ceil(self.m)
    }

    /// This shard's runs among `0..runs`, in order.
    pub fn runs(self, runs: u64) -> impl Iterator<Item = u64> {
        (self.k - 1..runs).step_by(self.m as usize)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.m)
    }
}

/// The seed of run `i` of a campaign with seed `seed`: SplitMix64 (Steele, Lea and Flood, 2014)
/// of the pair, so that neighbouring runs and neighbouring campaigns share nothing visible.
pub fn run_seed(seed: u64, i: u64) -> u64 {
    let mix = |mut z: u64| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    mix(mix(seed) ^ i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_cover_every_run_once() {
        for m in 1..=7u64 {
            let mut seen = vec![0; 50];
            for k in 1..=m {
                let s = Shard::new(k, m).unwrap();
                assert_eq!(s.count(50), s.runs(50).count() as u64);
                for i in s.runs(50) {
                    assert!(s.takes(i));
                    seen[i as usize] += 1;
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{m} shards: {seen:?}");
        }
        // Shard 2/4 of 10 runs: 1, 5, 9 (i mod 4 = 1).
        assert_eq!(
            Shard::parse("2/4").unwrap().runs(10).collect::<Vec<_>>(),
            [1, 5, 9]
        );
    }

    #[test]
    fn bad_shards_are_refused() {
        for bad in ["5/4", "0/4", "1/0", "4", "a/4", "2/b", "-1/4", ""] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(Shard::parse("4/4").unwrap(), Shard { k: 4, m: 4 });
    }

    #[test]
    fn kubernetes_index_is_zero_based() {
        assert_eq!(Shard::from_env(None, None).unwrap(), Shard::ALL);
        let e = Shard::from_env(None, Some("4")).unwrap_err();
        assert!(e.contains("JOB_COMPLETION_INDEX") && e.contains("--shard"), "{e}");
        assert_eq!(Shard::from_env(None, None).unwrap(), Shard::ALL);
        assert_eq!(
            Shard::from_env(Some("0"), Some("4")).unwrap(),
            Shard { k: 1, m: 4 }
        );
        assert_eq!(
            Shard::from_env(Some("3"), Some("4")).unwrap(),
            Shard { k: 4, m: 4 }
        );
        assert!(Shard::from_env(Some("4"), Some("4")).is_err());
        let e = Shard::from_env(Some("1"), None).unwrap_err();
        assert!(e.contains("HARVEMU_SHARDS"), "{e}");
        assert!(Shard::from_env(Some("x"), Some("4")).is_err());
    }

    #[test]
    fn run_seeds_differ_and_repeat() {
        // SplitMix64 of 0 is the first output of a SplitMix64 stream seeded with 0, a published
        // test value (0xE220A8397B1DCDAF).
        let mix0 = 0xE220_A839_7B1D_CDAF_u64;
        assert_eq!(run_seed(0, 0), {
            let mut z = mix0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        });
        let seeds: std::collections::BTreeSet<u64> = (0..1000).map(|i| run_seed(7, i)).collect();
        assert_eq!(seeds.len(), 1000);
        assert_eq!(run_seed(7, 3), run_seed(7, 3));
        assert_ne!(run_seed(7, 3), run_seed(8, 3));
    }
}
