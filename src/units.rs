//! Quantities as people write them on command lines and in job scripts:
//! durations (`90s`, `5m`), amounts of memory (`8G`), counts, seeds, tiles
//! (`3/16`); and bytes as people read them. Parsers return a one-line
//! message that says what was expected.

use std::time::Duration;

/// A duration as the command line takes it: seconds (`90`, `1.5`) or a
/// number with a unit (`90s`, `5m`, `1h`).
pub fn parse_duration(s: &str) -> Result<Duration, String> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix('h') {
        (n, 3600.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a duration (e.g. 90, 90s, 5m, 1h)"))?;
    let secs = v * scale;
    if !(secs.is_finite() && secs > 0.0 && secs <= 1e7) {
        return Err(format!(
            "'{s}': a duration must be more than 0 and at most 10^7 seconds"
        ));
    }
    Ok(Duration::from_secs_f64(secs))
}

/// An amount of memory: bytes, or a number with K, M, G or T (binary
/// units: `8G` is 8 GiB).
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, scale) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let scale: u64 = match c.to_ascii_uppercase() {
                'K' => 1 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => {
                    return Err(format!(
                        "'{s}' is not an amount of memory: use a number of bytes or K, M, G, T (e.g. 8G)"
                    ))
                }
            };
            (&t[..i], scale)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("'{s}' is not an amount of memory (e.g. 8G, 512M)"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{s}': the memory must be more than 0"));
    }
    Ok((v * scale as f64) as u64)
}

/// A count given on the command line: a whole number, at least 1.
pub fn parse_count(s: &str) -> Result<u32, String> {
    match s.trim().parse::<i64>() {
        Ok(v) if (1..=u32::MAX as i64).contains(&v) => Ok(v as u32),
        Ok(_) => Err(format!("must be a whole number from 1 to {}", u32::MAX)),
        Err(_) => Err("must be a whole number, at least 1".to_string()),
    }
}

/// A seed: a whole number from 0 to 2^64 - 1.
pub fn parse_seed(s: &str) -> Result<u64, String> {
    s.trim()
        .parse::<u64>()
        .map_err(|_| format!("must be a whole number from 0 to {}", u64::MAX))
}

/// A tile `I/N` (tile I, from 0, of N).
pub fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not a tile: write I/N, tile I (from 0) of N, e.g. 3/16");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (u32, u32) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(format!("'{s}': the tile I of I/N must be 0 to N-1"));
    }
    Ok((i, n))
}

/// Bytes for people: `512 B`, `1.5 GiB`.
pub fn human_bytes(b: u64) -> String {
    const U: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < U.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", U[u])
    }
}
