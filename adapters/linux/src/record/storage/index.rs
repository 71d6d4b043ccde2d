//! The index of a recording folder (`index.json`): every file the recording started, its
//! time span, size, why it is kept and why it was deleted. Its own module, on std and serde
//! alone, so that the fuzz workspace can read it as it is (`fuzz/fuzz_targets/
//! storage_index.rs`): the index is input — a folder can come from anywhere — and the names
//! it holds are joined to the folder's path for deleting.

use serde::{Deserialize, Serialize};

/// The index's format version.
pub const INDEX_VERSION: u32 = 1;

/// One log file of the folder.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SegmentEntry {
    /// File name in the folder.
    pub file: String,
    /// When recording into it began, Unix ms.
    pub started_ms: u64,
    /// When it was closed, Unix ms (none while it is being recorded, or after a crash).
    pub ended_ms: Option<u64>,
    /// Its size when last seen, bytes.
    pub bytes: u64,
    /// Why it is kept, if it is.
    pub protected: Option<String>,
    /// Why it was deleted, if it was (the entry stays, so that every deletion is on record).
    pub deleted: Option<String>,
}

/// The folder's index.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Index {
    /// [`INDEX_VERSION`].
    pub version: u32,
    /// Every file, oldest first.
    pub segments: Vec<SegmentEntry>,
}

/// Why a text is not an index this dash2sim reads.
#[derive(Debug)]
pub enum IndexError {
    /// Not JSON of the index's shape.
    Json(serde_json::Error),
    /// Another version of the index.
    Version(u32),
    /// An entry's file is not a plain `.d2slog` name in the folder.
    FileName(String),
}

impl std::fmt::Display for IndexError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IndexError::Json(e) => write!(f, "{e}"),
            IndexError::Version(v) => write!(f, "index version {v}, this dash2sim reads {INDEX_VERSION}"),
            IndexError::FileName(name) => {
                write!(f, "the index names {name:?}, which is not a log file of the folder (NAME.d2slog)")
            }
        }
    }
}

impl std::error::Error for IndexError {}

/// Whether `name` is a log file's name in the folder: no path, not hidden, `.d2slog`.
pub fn is_log_name(name: &str) -> bool {
    name.len() > ".d2slog".len()
        && name.ends_with(".d2slog")
        && !name.starts_with('.')
        && !name.contains(['/', '\\', '\0'])
}

impl Index {
    /// Parse and check an index: its version, and that every file it names is a log file
    /// in the folder (an entry `../x` would have the quota delete outside it).
    pub fn parse(text: &str) -> Result<Index, IndexError> {
        let index: Index = serde_json::from_str(text).map_err(IndexError::Json)?;
        if index.version != INDEX_VERSION {
            return Err(IndexError::Version(index.version));
        }
        if let Some(bad) = index.segments.iter().find(|e| !is_log_name(&e.file)) {
            return Err(IndexError::FileName(bad.file.clone()));
        }
        Ok(index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn index_naming(file: &str) -> String {
        serde_json::json!({"version": 1, "segments": [{
            "file": file, "started_ms": 1, "ended_ms": 2, "bytes": 3, "protected": null, "deleted": null
        }]})
        .to_string()
    }

    #[test]
    fn an_index_naming_a_file_outside_the_folder_is_refused() {
        assert!(Index::parse(&index_naming("dash2sim-1-0000.d2slog")).is_ok());
        for bad in ["../../etc/passwd.d2slog", "/tmp/x.d2slog", "sub/x.d2slog", ".d2slog", "x.txt", "..\\x.d2slog", ""]
        {
            let e = Index::parse(&index_naming(bad)).expect_err(bad);
            assert!(matches!(e, IndexError::FileName(_)), "{bad}: {e}");
            assert!(e.to_string().contains("not a log file of the folder"));
        }
        assert!(matches!(Index::parse(r#"{"version": 2, "segments": []}"#), Err(IndexError::Version(2))));
        assert!(matches!(Index::parse("{"), Err(IndexError::Json(_))));
    }
}
