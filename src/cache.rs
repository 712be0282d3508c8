//! lamina's on-disk cache ($LAMINA_CACHE, else ~/.cache/lamina), where nothing read back is trusted. Every entry is
//! a header (magic, payload length, checksum of the payload) and its payload, written atomically: to a temporary file
//! of its own (process, thread and call), then renamed into place. So a truncated, zeroed or garbage file is detected
//! and rebuilt, never read as data; concurrent writers of one entry leave one complete file (the same bits: what they
//! write is deterministic); and a cache that cannot be written (read-only, full) costs only a recomputation: lamina
//! computes in memory and warns once (`take_warning`: the Python bindings issue it as a UserWarning). The cache is
//! bounded ($LAMINA_CACHE_LIMIT_MB, 2048 MiB by default): each write removes the least recently used entries beyond
//! it (`prune`). The tables (tables/mod.rs) and the reference results (python/lamina/reference.py) are cached here.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{SystemTime, UNIX_EPOCH};

/// The first bytes of every entry.
const MAGIC: [u8; 8] = *b"lamina\x01\x00";
/// Magic, payload length and checksum.
const HEADER: usize = 24;

/// The cache's root: $LAMINA_CACHE, else ~/.cache/lamina.
pub fn root() -> Option<PathBuf> {
    std::env::var_os("LAMINA_CACHE")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache").join("lamina")))
}

/// FNV-1a over the payload's 64-bit words (and its tail bytes): what the header's checksum holds.
fn checksum(payload: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut words = payload.chunks_exact(8);
    for w in &mut words {
        h = (h ^ u64::from_le_bytes(w.try_into().expect("8 bytes"))).wrapping_mul(0x0100_0000_01b3);
    }
    for &b in words.remainder() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// The payload of the entry at `path`, or None when there is none or it is not intact (wrong magic, length or
/// checksum), in which case the caller rebuilds it.
pub fn read(path: &Path) -> Option<Vec<u8>> {
    let mut bytes = std::fs::read(path).ok()?;
    let header = bytes.get(..HEADER)?;
    let len = u64::from_le_bytes(header[8..16].try_into().ok()?);
    let sum = u64::from_le_bytes(header[16..24].try_into().ok()?);
    let intact = header[..8] == MAGIC && bytes.len() as u64 == HEADER as u64 + len && checksum(&bytes[HEADER..]) == sum;
    if intact {
        // Used now: the last to be removed when the cache is over its bound (`prune`). A read-only cache keeps its times.
        let _ = std::fs::File::options().write(true).open(path).and_then(|f| f.set_modified(SystemTime::now()));
    }
    intact.then(|| bytes.split_off(HEADER))
}

/// The cache's bound in bytes: $LAMINA_CACHE_LIMIT_MB mebibytes, else 2048.
fn limit() -> u64 {
    std::env::var("LAMINA_CACHE_LIMIT_MB").ok().and_then(|v| v.trim().parse::<u64>().ok()).unwrap_or(2048) << 20
}

/// Removes the least recently used entries under `root` (by modification time, which `read` refreshes), `keep` and
/// other writers' temporary files aside, until the entries take at most `limit` bytes. A fit with `tabulated` writes
/// a table per evaluation (0.8 MiB each), which would otherwise fill the disk. Entries another process removes or reads
/// meanwhile cost it a recomputation at most: nothing on disk is trusted.
pub fn prune(root: &Path, limit: u64, keep: &Path) {
    let mut entries = Vec::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for e in std::fs::read_dir(&folder).into_iter().flatten().flatten() {
            let (Ok(meta), path) = (e.metadata(), e.path()) else { continue };
            let temporary = path.extension().is_some_and(|x| x.to_string_lossy().starts_with("tmp-"));
            if meta.is_dir() {
                folders.push(path);
            } else if meta.is_file() && !temporary {
                entries.push((meta.modified().unwrap_or(UNIX_EPOCH), meta.len(), path));
            }
        }
    }
    let mut total: u64 = entries.iter().map(|e| e.1).sum();
    entries.sort();
    for (_, len, path) in entries {
        if total <= limit {
            break;
        }
        if path != keep && std::fs::remove_file(&path).is_ok() {
            total -= len;
        }
    }
}

/// Writes `payload` as the entry at `path`, atomically; a failure (a read-only or full cache) is warned about once
/// and otherwise ignored: the caller has the data in memory.
pub fn write(path: &Path, payload: &[u8]) {
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let call = CALLS.fetch_add(1, Ordering::Relaxed);
    let thread = format!("{:?}", std::thread::current().id()).replace(|c: char| !c.is_ascii_digit(), "");
    let tmp = path.with_extension(format!("tmp-{}-{thread}-{call}", std::process::id()));
    let mut bytes = Vec::with_capacity(HEADER + payload.len());
    bytes.extend_from_slice(&MAGIC);
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&checksum(payload).to_le_bytes());
    bytes.extend_from_slice(payload);
    let written = path
        .parent()
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|_| std::fs::write(&tmp, &bytes))
        .and_then(|_| std::fs::rename(&tmp, path));
    if written.is_ok() {
        if let Some(root) = root().filter(|r| path.starts_with(r)) {
            prune(&root, limit(), path);
        }
    }
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        warn_once(&format!(
            "lamina could not write its cache at {} ({e}); results are computed in memory and not kept. Set \
             LAMINA_CACHE to a writable folder to keep them.",
            path.display()
        ));
    }
}

/// The cache's warning, waiting for the bindings to issue it (`take_warning`): recorded, not issued, where the cache is
/// written, which may be a thread inside a table's initialisation that another thread waits on while holding Python's
/// lock.
static PENDING: Mutex<Option<String>> = Mutex::new(None);

/// The first of the cache's warnings in this process is kept for `take_warning`; the others are dropped.
fn warn_once(message: &str) {
    static WARNED: AtomicBool = AtomicBool::new(false);
    if !WARNED.swap(true, Ordering::Relaxed) {
        *PENDING.lock().unwrap_or_else(|e| e.into_inner()) = Some(message.to_string());
    }
}

/// The cache's warning not yet issued, if any (once).
pub fn take_warning() -> Option<String> {
    PENDING.lock().unwrap_or_else(|e| e.into_inner()).take()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("lamina-cache-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir.join("entry")
    }

    #[test]
    fn an_entry_reads_back_as_written_and_every_damage_is_detected() {
        let path = scratch("damage");
        let payload: Vec<u8> = (0..1000u32).flat_map(|k| (k as f32).sqrt().to_le_bytes()).collect();
        write(&path, &payload);
        assert_eq!(read(&path).as_deref(), Some(&payload[..]));
        let good = std::fs::read(&path).unwrap();
        let truncated = good[..good.len() - 1].to_vec();
        let zeroed = vec![0u8; good.len()];
        let mut flipped = good.clone();
        flipped[HEADER + 500] ^= 1;
        let garbage: Vec<u8> = (0..good.len()).map(|k| (k * 7919 % 251) as u8).collect();
        for (what, bytes) in [("truncated", truncated), ("zeroed", zeroed), ("bit flip", flipped), ("garbage", garbage)]
        {
            std::fs::write(&path, bytes).unwrap();
            assert_eq!(read(&path), None, "{what}");
        }
        std::fs::write(&path, b"").unwrap();
        assert_eq!(read(&path), None, "empty");
    }

    #[test]
    fn over_its_bound_the_cache_removes_its_least_recently_used_entries() {
        // Five entries used a minute apart, the oldest then read (used now): a bound of three entries keeps it, the
        // newest and the one being written (the second oldest), and removes the two least recently used of the rest.
        let root = scratch("prune").parent().unwrap().to_path_buf();
        let payload = vec![7u8; 1000];
        let entry = |k: usize| root.join("tables").join("hash").join(format!("entry-{k}"));
        for k in 0..5 {
            write(&entry(k), &payload);
            let when = SystemTime::now() - std::time::Duration::from_secs(60 * (10 - k as u64));
            std::fs::File::options().write(true).open(entry(k)).unwrap().set_modified(when).unwrap();
        }
        assert!(read(&entry(0)).is_some());
        prune(&root, 3 * (HEADER as u64 + 1000), &entry(1));
        let left: Vec<bool> = (0..5).map(|k| entry(k).exists()).collect();
        assert_eq!(left, [true, true, false, false, true]);
    }

    #[test]
    fn concurrent_writers_leave_one_intact_entry() {
        let path = scratch("concurrent");
        let payload: Vec<u8> = (0..1 << 20).map(|k: u32| (k % 253) as u8).collect();
        std::thread::scope(|s| {
            for _ in 0..8 {
                s.spawn(|| write(&path, &payload));
            }
        });
        assert_eq!(read(&path).as_deref(), Some(&payload[..]));
        let leftovers = std::fs::read_dir(path.parent().unwrap()).unwrap().count();
        assert_eq!(leftovers, 1, "no temporary file left behind");
    }
}
