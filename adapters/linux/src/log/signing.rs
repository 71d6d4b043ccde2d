//! Signed logs on the desktop: the device's key files (`dash2sim keygen`), and the check of
//! a log's — or a recording folder's — segment signatures against a public key
//! (`inspect --verify-key`, `finish --require-signed`, the corpus job). The format and the
//! verdicts are the core's ([`dash2sim_core::binlog::signature`], `docs/binlog.md`).

use std::io::Write as _;
use std::path::{Path, PathBuf};

use dash2sim_core::binlog::signature::{key_id, Seal, SealCheck, Sealer};
use dash2sim_core::binlog::Event;
use serde::Serialize;

use super::LogContents;
use crate::{Error, Result};

/// First line of a secret key file.
const SECRET_TAG: &str = "dash2sim-ed25519-secret-key";

/// Hex of bytes, lower case.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex32(text: &str) -> Option<[u8; 32]> {
    let text = text.trim();
    if text.len() != 64 || !text.is_ascii() {
        return None;
    }
    let mut out = [0u8; 32];
    for (k, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&text[2 * k..2 * k + 2], 16).ok()?;
    }
    Some(out)
}

/// A new device key pair: `PREFIX.key` (the secret, readable by its owner only) and
/// `PREFIX.pub` (the public key, 64 hex digits). Refuses to overwrite either. Returns both
/// paths and the public key.
pub fn keygen(prefix: &Path) -> Result<(PathBuf, PathBuf, [u8; 32])> {
    let secret_path = prefix.with_extension("key");
    let public_path = prefix.with_extension("pub");
    for p in [&secret_path, &public_path] {
        if p.exists() {
            return Err(Error::invalid(format!("{}: exists; a key is never overwritten", p.display())));
        }
    }
    let mut seed = [0u8; 32];
    getrandom::fill(&mut seed).map_err(|e| Error::invalid(format!("no randomness from the system: {e}")))?;
    let public = Sealer::new(&seed).public_key();
    let mut file = secret_file(&secret_path)?;
    writeln!(file, "{SECRET_TAG}\n{}", hex(&seed)).map_err(|e| Error::file(&secret_path, e))?;
    std::fs::write(&public_path, format!("{}\n", hex(&public))).map_err(|e| Error::file(&public_path, e))?;
    Ok((secret_path, public_path, public))
}

#[cfg(unix)]
fn secret_file(path: &Path) -> Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt as _;
    std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(path).map_err(|e| Error::file(path, e))
}

#[cfg(not(unix))]
fn secret_file(path: &Path) -> Result<std::fs::File> {
    std::fs::OpenOptions::new().write(true).create_new(true).open(path).map_err(|e| Error::file(path, e))
}

/// A device's secret key (the Ed25519 seed); never printed.
#[derive(Clone)]
pub struct SecretKey([u8; 32]);

impl std::fmt::Debug for SecretKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SecretKey(…)")
    }
}

impl SecretKey {
    /// The key with this seed.
    pub fn from_seed(seed: [u8; 32]) -> Self {
        SecretKey(seed)
    }

    /// The key in a secret key file written by [`keygen`].
    pub fn read(path: &Path) -> Result<SecretKey> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
        let mut lines = text.lines();
        if lines.next().map(str::trim) != Some(SECRET_TAG) {
            return Err(Error::file(path, format!("not a dash2sim secret key (its first line is not `{SECRET_TAG}`)")));
        }
        let seed = lines.next().and_then(unhex32);
        seed.map(SecretKey).ok_or_else(|| Error::file(path, "the key is not 64 hex digits on the second line"))
    }

    /// A sealer signing with it, its chain starting afresh.
    pub fn sealer(&self) -> Sealer {
        Sealer::new(&self.0)
    }
}

/// A public key given as 64 hex digits or as a file holding them (`PREFIX.pub`).
pub fn read_public(given: &str) -> Result<[u8; 32]> {
    if let Some(key) = unhex32(given) {
        return Ok(key);
    }
    let path = Path::new(given);
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::invalid(format!("{given}: neither 64 hex digits nor a public key file ({e})")))?;
    unhex32(&text).ok_or_else(|| Error::file(path, "not a public key (64 hex digits)"))
}

/// A segment's verdict.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SegmentSeal {
    /// Its sequence number in the file.
    pub seq: u64,
    /// `ok`, `ok (chain starts)`, `bad signature`, … ([`Seal::name`]).
    pub verdict: &'static str,
    /// Whether it is signed by the key and unaltered ([`Seal::is_trusted`]).
    pub trusted: bool,
    /// The key id it was signed with, when another key's (hex).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub other_key: Option<String>,
}

impl SegmentSeal {
    fn new(seq: u64, seal: Seal) -> Self {
        let other_key = match seal {
            Seal::OtherKey(id) => Some(hex(&id)),
            _ => None,
        };
        SegmentSeal { seq, verdict: seal.name(), trusted: seal.is_trusted(), other_key }
    }
}

/// The signatures of one file.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct FileSeals {
    /// The file.
    pub file: String,
    /// Its segments in order.
    pub segments: Vec<SegmentSeal>,
}

impl FileSeals {
    /// Segments signed by the key and unaltered.
    pub fn trusted(&self) -> usize {
        self.segments.iter().filter(|s| s.trusted).count()
    }

    /// The first segment that is not, if any.
    pub fn first_untrusted(&self) -> Option<&SegmentSeal> {
        self.segments.iter().find(|s| !s.trusted)
    }
}

/// A log to check, in recording order.
#[derive(Clone, Copy, Debug)]
pub struct Checked<'a> {
    /// Its name in the verdicts.
    pub name: &'a str,
    /// Its segment starts and signature trailers ([`LogContents::signing`]).
    pub signing: &'a [Event],
    /// The file before it was deleted by loop recording (the folder's index says so): its
    /// first segment is judged as the first of a chain ("continues a segment not given").
    pub after_deleted: bool,
}

/// Judge the segments of logs read in recording order (one file, or a folder's files oldest
/// first) against `public`: the chain runs across the files, so a file removed from the
/// middle or moved shows as a broken chain in the file after it.
pub fn check<'a>(public: &[u8; 32], logs: impl IntoIterator<Item = Checked<'a>>) -> Result<Vec<FileSeals>> {
    let mut check = SealCheck::new(public).map_err(Error::other)?;
    Ok(logs
        .into_iter()
        .map(|Checked { name, signing, after_deleted }| {
            if after_deleted {
                check.forget_chain();
            }
            let mut segments: Vec<SegmentSeal> = signing
                .iter()
                .filter_map(|e| check.on_event(e))
                .map(|(seq, seal)| SegmentSeal::new(seq, seal))
                .collect();
            segments.extend(check.end_of_file().map(|(seq, seal)| SegmentSeal::new(seq, seal)));
            FileSeals { file: name.to_owned(), segments }
        })
        .collect())
}

/// Refuse a log unless every segment is signed by `public` and unaltered, in an unbroken
/// chain (`finish --require-signed`, the corpus job); the error names the first segment
/// that is not, and why.
pub fn require_signed<R>(public: &[u8; 32], name: &str, log: &LogContents<R>) -> Result<()> {
    let seals = check(public, [Checked { name, signing: &log.signing, after_deleted: false }])?;
    let file = &seals[0];
    if file.segments.is_empty() {
        return Err(Error::invalid(format!("{name}: not signed: the log holds no segment")));
    }
    match file.first_untrusted() {
        None => Ok(()),
        Some(s) => {
            let key = s.other_key.as_ref().map(|id| format!(" (key id {id})")).unwrap_or_default();
            Err(Error::invalid(format!(
                "{name}: not signed by key {}: segment {} of {}: {}{key}",
                hex(&key_id(public)),
                s.seq,
                file.segments.len(),
                s.verdict
            )))
        }
    }
}
