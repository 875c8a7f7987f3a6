//! `render --shard I/N`: the I-th of N contiguous blocks of a frame range, for a render farm.
//! Blocks are contiguous so that each worker keeps its static tree, instances and refit history
//! from one frame to the next. `auto` takes I and N from the scheduler's variables.

use std::fmt;

/// One block of a split frame range: `index` counts from 1 to `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

/// What `--shard` was given: a fixed shard, or one to read from the scheduler's variables
/// (`count`: the total a Kubernetes Indexed Job cannot export).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardArg {
    Fixed(Shard),
    Auto { count: Option<u32> },
}

/// Parses `I/N`, `auto` or `auto/N`.
pub fn parse_shard(s: &str) -> Result<ShardArg, String> {
    let count = |n: &str| match n.trim().parse::<u32>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "'{n}' is not a shard count (a whole number from 1)"
        )),
    };
    if s == "auto" {
        return Ok(ShardArg::Auto { count: None });
    }
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("'{s}' is not a shard: write I/N (such as 2/8), auto or auto/N"))?;
    if i == "auto" {
        return Ok(ShardArg::Auto {
            count: Some(count(n)?),
        });
    }
    let count = count(n)?;
    let index: u32 = i
        .trim()
        .parse()
        .map_err(|_| format!("'{i}' is not a shard number"))?;
    if !(1..=count).contains(&index) {
        return Err(format!(
            "shard {index}/{count}: I must be between 1 and {count}"
        ));
    }
    Ok(ShardArg::Fixed(Shard { index, count }))
}

impl ShardArg {
    /// The shard itself, reading the scheduler's variables through `var` for `auto`.
    pub fn resolve(&self, var: impl Fn(&str) -> Option<String>) -> Result<Shard, String> {
        let count = match *self {
            ShardArg::Fixed(s) => return Ok(s),
            ShardArg::Auto { count } => count,
        };
        let number = |name: &str| -> Result<Option<u32>, String> {
            var(name)
                .map(|v| {
                    v.trim()
                        .parse::<u32>()
                        .map_err(|_| format!("{name}={v} is not a whole number"))
                })
                .transpose()
        };
        let shard = if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            // Slurm: a job array `--array=MIN-MAX[:STEP]` of COUNT tasks.
            let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            let total = number("SLURM_ARRAY_TASK_COUNT")?
                .or(count)
                .ok_or("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not")?;
            if id < min || (id - min) % step != 0 {
                return Err(format!(
                    "SLURM_ARRAY_TASK_ID={id} is not in the array {min}..:{step}"
                ));
            }
            Shard {
                index: (id - min) / step + 1,
                count: total,
            }
        } else if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            // Kubernetes Indexed Job: indices 0..completions-1; the total is not exported.
            let count = count.ok_or(
                "JOB_COMPLETION_INDEX is set but Kubernetes exports no total: write --shard auto/N \
                 with N the Job's completions",
            )?;
            Shard {
                index: index + 1,
                count,
            }
        } else {
            return Err("--shard auto: no scheduler variables are set (Slurm's \
                        SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, or Kubernetes' \
                        JOB_COMPLETION_INDEX with --shard auto/N); give the shard as I/N"
                .into());
        };
        if let Some(n) = count
            && n != shard.count
        {
            return Err(format!(
                "--shard auto/{n}, but the scheduler runs {} tasks",
                shard.count
            ));
        }
        if shard.index > shard.count {
            return Err(format!(
                "the scheduler's task {} is beyond its {} tasks",
                shard.index, shard.count
            ));
        }
        Ok(shard)
    }
}

impl Shard {
    /// This shard's frames of `start..=end`, or `None` when the range has fewer frames than
    /// shards and this one is left without any. Block sizes differ by at most one frame.
    pub fn block(&self, start: u32, end: u32) -> Option<(u32, u32)> {
        let frames = u64::from(end - start) + 1;
        let edge = |i: u32| start as u64 + frames * u64::from(i) / u64::from(self.count);
        let (a, b) = (edge(self.index - 1), edge(self.index));
        (b > a).then(|| (a as u32, (b - 1) as u32))
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(s: &str) -> Shard {
        match parse_shard(s).unwrap() {
            ShardArg::Fixed(s) => s,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn blocks_cover_the_range_once_in_order() {
        for (start, end) in [(0, 0), (0, 9), (5, 17), (1, 2)] {
            for count in 1..=12 {
                let mut next = start;
                for index in 1..=count {
                    if let Some((a, b)) = (Shard { index, count }).block(start, end) {
                        assert_eq!(a, next, "{index}/{count} of {start}..{end}");
                        assert!(b >= a);
                        next = b + 1;
                    }
                }
                assert_eq!(next, end + 1, "{count} shards of {start}..{end}");
            }
        }
        assert_eq!(fixed("2/3").block(0, 9), Some((3, 5)));
        assert_eq!(fixed("3/3").block(0, 9), Some((6, 9)));
        assert_eq!(fixed("2/3").block(4, 4), None);
    }

    #[test]
    fn arguments_parse_or_say_why_not() {
        assert_eq!(fixed("2/8"), Shard { index: 2, count: 8 });
        assert_eq!(parse_shard("auto"), Ok(ShardArg::Auto { count: None }));
        assert_eq!(parse_shard("auto/4"), Ok(ShardArg::Auto { count: Some(4) }));
        for bad in ["0/3", "4/3", "1/0", "x/2", "3", "auto/x", ""] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn auto_reads_slurm_and_kubernetes() {
        let auto = ShardArg::Auto { count: None };
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "7"),
            ("SLURM_ARRAY_TASK_MIN", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ];
        assert_eq!(auto.resolve(env(&slurm)), Ok(Shard { index: 3, count: 4 }));
        let stepped = [
            ("SLURM_ARRAY_TASK_ID", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ];
        assert_eq!(
            auto.resolve(env(&stepped)),
            Ok(Shard { index: 3, count: 3 })
        );
        let k8s = [("JOB_COMPLETION_INDEX", "0")];
        assert_eq!(
            ShardArg::Auto { count: Some(5) }.resolve(env(&k8s)),
            Ok(Shard { index: 1, count: 5 })
        );
        assert!(auto.resolve(env(&k8s)).unwrap_err().contains("auto/N"));
        assert!(auto.resolve(env(&[])).unwrap_err().contains("no scheduler"));
        assert!(
            ShardArg::Auto { count: Some(5) }
                .resolve(env(&[("JOB_COMPLETION_INDEX", "5")]))
                .is_err()
        );
    }
}
