//! Loop recording: a live recording's folder kept within a quota, as a dashcam keeps its SD
//! card — when the folder would outgrow it (or the file system's free space would fall
//! below a floor), the oldest closed files go first, except the protected ones: a file that
//! holds a collision, a harsh braking or a verified window, or that the user marked. When
//! only protected files are left to
//! delete, the oldest of those goes, and the log says so: recording never stops.
//!
//! The folder's `index.json` names every file the recording started, with its time span,
//! size, protection and, once deleted, why. It is replaced atomically (written beside, then
//! renamed), so that a power cut leaves the old index or the new one, never half of one.

use std::path::{Path, PathBuf};

use dash2sim_core::binlog::HEADER_LEN;

mod index;
pub use index::{is_log_name, Index, IndexError, SegmentEntry, INDEX_VERSION};

use crate::{Error, Result};

/// The folder's index file.
pub const INDEX_FILE: &str = "index.json";
/// A file of this name in the folder marks the file being recorded as kept (then removed).
pub const KEEP_FILE: &str = "KEEP";
/// Why a file created but never written before a crash was removed.
const EMPTY: &str = "empty after a crash";

/// How much of the disk a recording may use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StoragePolicy {
    /// The folder's log files together stay below this many bytes.
    pub quota: Option<u64>,
    /// The file system keeps at least this many bytes free.
    pub min_free: Option<u64>,
}

/// A file deleted to keep within the policy.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Deletion {
    /// Its name.
    pub file: String,
    /// Its size.
    pub bytes: u64,
    /// Why it had been kept, when only protected files were left to delete.
    pub protected: Option<String>,
}

/// The index of `dir` (an error naming the file when it is missing, unreadable or not an
/// index this dash2sim reads).
pub fn read_index(dir: &Path) -> Result<Index> {
    let path = dir.join(INDEX_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::file(&path, e))?;
    Index::parse(&text).map_err(|e| Error::file(&path, e))
}

/// Now, Unix ms.
pub fn now_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

/// The name of the `index`th file of a run started at `started` (Unix ms): names sort by
/// time, and a logger restarted at once gets a new start time, so no file is overwritten.
pub fn file_name(started: u64, index: u32) -> String {
    format!("dash2sim-{started}-{index:04}.d2slog")
}

/// A recording folder under a [`StoragePolicy`].
#[derive(Debug)]
pub struct Storage {
    dir: PathBuf,
    policy: StoragePolicy,
    index: Index,
}

impl Storage {
    /// The folder `dir` (created if missing), continuing its index when it has one (a
    /// restarted logger), and put right after a crash or a power cut: a file created just
    /// before it named, one never written removed, an entry whose file is gone marked
    /// deleted, an open entry closed with its size.
    pub fn open(dir: &Path, policy: StoragePolicy) -> Result<Storage> {
        std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
        let index = if dir.join(INDEX_FILE).exists() {
            read_index(dir)?
        } else {
            Index { version: INDEX_VERSION, segments: Vec::new() }
        };
        let mut storage = Storage { dir: dir.to_path_buf(), policy, index };
        storage.recover()?;
        storage.save()?;
        Ok(storage)
    }

    /// What a crash can leave between a file and the index (each step of the index is
    /// atomic, but a file is created, and deleted, beside it): an entry left open is closed
    /// with its size on disk; a file the index does not name (created just before the crash)
    /// is named; a file shorter than a log's header (created, never written) is removed; an
    /// entry whose file is gone (deleted just before the crash) is marked deleted.
    fn recover(&mut self) -> Result<()> {
        let dir = &self.dir;
        for entry in self.index.segments.iter_mut().filter(|e| e.deleted.is_none()) {
            entry.ended_ms.get_or_insert(entry.started_ms);
            match std::fs::metadata(dir.join(&entry.file)) {
                Ok(m) if m.len() < HEADER_LEN as u64 => {
                    let path = dir.join(&entry.file);
                    std::fs::remove_file(&path).map_err(|e| Error::file(&path, e))?;
                    entry.deleted = Some(EMPTY.to_owned());
                }
                Ok(m) => entry.bytes = m.len(),
                Err(_) => entry.deleted = Some("missing after a crash".to_owned()),
            }
        }
        let mut unnamed: Vec<(String, std::fs::Metadata)> = std::fs::read_dir(dir)
            .map_err(|e| Error::file(dir, e))?
            .filter_map(|e| e.ok())
            .filter_map(|e| Some((e.file_name().into_string().ok()?, e.metadata().ok()?)))
            .filter(|(name, m)| m.is_file() && is_log_name(name))
            .filter(|(name, _)| !self.index.segments.iter().any(|e| &e.file == name))
            .collect();
        unnamed.sort_by(|a, b| a.0.cmp(&b.0));
        for (file, m) in unnamed {
            let modified = m.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
            let at = modified.map_or_else(now_ms, |d| d.as_millis() as u64);
            let mut deleted = None;
            if m.len() < HEADER_LEN as u64 {
                let path = dir.join(&file);
                std::fs::remove_file(&path).map_err(|e| Error::file(&path, e))?;
                deleted = Some(EMPTY.to_owned());
            }
            self.index.segments.push(SegmentEntry {
                file,
                started_ms: at,
                ended_ms: Some(at),
                bytes: m.len(),
                protected: None,
                deleted,
            });
        }
        Ok(())
    }

    /// The index as it stands.
    pub fn index(&self) -> &Index {
        &self.index
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Recording into `path` (a file of the folder) begins.
    pub fn started(&mut self, path: &Path) -> Result<()> {
        let file = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        self.index.segments.push(SegmentEntry {
            file,
            started_ms: now_ms(),
            ended_ms: None,
            bytes: 0,
            protected: None,
            deleted: None,
        });
        self.save()
    }

    /// The file being recorded is kept, for `reason`; true when it was not yet.
    pub fn protect(&mut self, reason: &str) -> Result<bool> {
        let Some(current) = self.index.segments.last_mut().filter(|e| e.ended_ms.is_none()) else { return Ok(false) };
        if current.protected.is_some() {
            return Ok(false);
        }
        current.protected = Some(reason.to_owned());
        self.save()?;
        Ok(true)
    }

    /// The file being recorded was closed.
    pub fn closed(&mut self) -> Result<()> {
        if let Some(current) = self.index.segments.last_mut().filter(|e| e.ended_ms.is_none()) {
            current.ended_ms = Some(now_ms());
            current.bytes = std::fs::metadata(self.dir.join(&current.file)).map_or(current.bytes, |m| m.len());
        }
        self.save()
    }

    /// Bytes of the folder's files on disk (and of the index), and the file system's free
    /// bytes.
    fn usage(&mut self) -> (u64, Option<u64>) {
        let mut total = std::fs::metadata(self.dir.join(INDEX_FILE)).map_or(0, |m| m.len());
        for entry in self.index.segments.iter_mut().filter(|e| e.deleted.is_none()) {
            entry.bytes = std::fs::metadata(self.dir.join(&entry.file)).map_or(0, |m| m.len());
            total += entry.bytes;
        }
        let free = rustix::fs::statvfs(&self.dir).ok().map(|s| s.f_bavail.saturating_mul(s.f_frsize));
        (total, free)
    }

    /// Delete the oldest closed files until the folder, with `headroom` bytes more, is within
    /// the policy: unprotected ones first, then — only when nothing else is left — protected
    /// ones. The file being recorded is never deleted. Returns what was deleted.
    pub fn enforce(&mut self, headroom: u64) -> Result<Vec<Deletion>> {
        let mut deleted = Vec::new();
        loop {
            let (total, free) = self.usage();
            let over_quota = self.policy.quota.is_some_and(|q| total + headroom > q);
            let under_floor =
                matches!((self.policy.min_free, free), (Some(floor), Some(free)) if free < floor + headroom);
            if !(over_quota || under_floor) {
                break;
            }
            let closed = |protected: bool| {
                move |e: &&mut SegmentEntry| {
                    e.deleted.is_none() && e.ended_ms.is_some() && e.protected.is_some() == protected
                }
            };
            let victim = match self.index.segments.iter_mut().find(closed(false)) {
                Some(v) => v,
                None => match self.index.segments.iter_mut().find(closed(true)) {
                    Some(v) => v,
                    None => break,
                },
            };
            let path = self.dir.join(&victim.file);
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(Error::file(&path, e)),
            }
            let why = if over_quota { "over the quota" } else { "below the free-space floor" };
            victim.deleted = Some(why.to_owned());
            deleted.push(Deletion {
                file: victim.file.clone(),
                bytes: victim.bytes,
                protected: victim.protected.clone(),
            });
        }
        if !deleted.is_empty() {
            self.save()?;
        }
        Ok(deleted)
    }

    /// Write the index beside and rename it into place.
    fn save(&self) -> Result<()> {
        let path = self.dir.join(INDEX_FILE);
        let temporary = self.dir.join(format!("{INDEX_FILE}.partial"));
        let text = serde_json::to_string_pretty(&self.index).map_err(Error::other)?;
        std::fs::write(&temporary, text).map_err(|e| Error::file(&temporary, e))?;
        std::fs::rename(&temporary, &path).map_err(|e| Error::file(&path, e))
    }
}

/// `"64k"`, `"500M"`, `"2G"`, `"1048576"`: a size in bytes (binary multiples).
pub fn parse_size(text: &str) -> Result<u64> {
    let text = text.trim();
    let (number, unit) = text.split_at(text.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(text.len()));
    let scale: u64 = match unit.to_ascii_lowercase().trim_end_matches("ib").trim_end_matches('b') {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return Err(Error::invalid(format!("size {text:?}: the unit is one of k, M, G, T"))),
    };
    let value: f64 = number.trim().parse().map_err(|_| Error::invalid(format!("size {text:?} is not a number")))?;
    if !(value.is_finite() && value > 0.0) {
        return Err(Error::invalid(format!("size {text:?} must be positive")));
    }
    Ok((value * scale as f64) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("dash2sim-storage-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("dir");
        dir
    }

    fn record(storage: &mut Storage, dir: &Path, name: &str, bytes: usize, keep: bool) {
        let path = dir.join(name);
        storage.started(&path).expect("start");
        std::fs::write(&path, vec![0u8; bytes]).expect("write");
        if keep {
            assert!(storage.protect("marked by the user").expect("protect"));
        }
        storage.closed().expect("close");
    }

    #[test]
    fn the_oldest_unprotected_files_go_first_and_protected_ones_only_when_nothing_else_is_left() {
        let dir = folder("order");
        let mut storage = Storage::open(&dir, StoragePolicy { quota: Some(10_000), min_free: None }).expect("open");
        record(&mut storage, &dir, "a.d2slog", 3000, true);
        record(&mut storage, &dir, "b.d2slog", 3000, false);
        record(&mut storage, &dir, "c.d2slog", 3000, false);
        assert!(storage.enforce(0).expect("enforce").is_empty(), "9 000 bytes and the index fit");
        record(&mut storage, &dir, "d.d2slog", 3000, false);
        let gone = storage.enforce(0).expect("enforce");
        assert_eq!(gone.iter().map(|d| d.file.as_str()).collect::<Vec<_>>(), ["b.d2slog"], "the oldest unprotected");
        assert!(dir.join("a.d2slog").exists() && !dir.join("b.d2slog").exists());
        // Only protected files left besides the newest: the oldest protected one goes.
        record(&mut storage, &dir, "e.d2slog", 7000, true);
        let gone = storage.enforce(0).expect("enforce");
        assert_eq!(gone.iter().map(|d| d.file.as_str()).collect::<Vec<_>>(), ["c.d2slog", "d.d2slog", "a.d2slog"]);
        assert_eq!(gone[2].protected.as_deref(), Some("marked by the user"));
        // Every deletion is in the index, which another reader sees whole.
        let index = read_index(&dir).expect("index");
        let deleted: Vec<_> = index.segments.iter().filter(|e| e.deleted.is_some()).map(|e| e.file.as_str()).collect();
        assert_eq!(deleted, ["a.d2slog", "b.d2slog", "c.d2slog", "d.d2slog"]);
        assert!(!dir.join(format!("{INDEX_FILE}.partial")).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_restarted_logger_continues_the_index_and_closes_what_a_crash_left_open() {
        let dir = folder("restart");
        let mut storage = Storage::open(&dir, StoragePolicy::default()).expect("open");
        storage.started(&dir.join("x.d2slog")).expect("start");
        std::fs::write(dir.join("x.d2slog"), [1u8; 100]).expect("write");
        drop(storage);
        let storage = Storage::open(&dir, StoragePolicy::default()).expect("reopen");
        let entry = &storage.index().segments[0];
        assert_eq!((entry.bytes, entry.ended_ms.is_some()), (100, true));
        std::fs::write(dir.join(INDEX_FILE), r#"{"version": 9, "segments": []}"#).expect("write");
        assert!(read_index(&dir).expect_err("version").to_string().contains("index version 9"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn sizes_read_with_their_units() {
        assert_eq!(parse_size("64k").expect("k"), 65_536);
        assert_eq!(parse_size("1.5G").expect("G"), 1_610_612_736);
        assert_eq!(parse_size("500MiB").expect("MiB"), 524_288_000);
        assert_eq!(parse_size("1000").expect("bytes"), 1000);
        assert!(parse_size("12q").is_err() && parse_size("-1M").is_err() && parse_size("M").is_err());
    }
}
