//! Signed segments (format v1.5): every segment of a log can end with a **signature
//! trailer**, an Ed25519 signature by the device's key over the segment's bytes and a link
//! to the previous segment's signature, so that a log shows whether it came unaltered from
//! the device that claims it — and whether a segment in the middle was removed or moved.
//!
//! The trailer is a frame of kind [`SIGNATURE`] right after the segment's index frame;
//! readers of v1.4 and before skip it as an unknown kind. Its payload:
//!
//! ```text
//! format (1 B, 1) · key id (8 B) · link (16 B) · signature (64 B)
//! ```
//!
//! * the **digest** is SHA-512 over the segment's bytes, from its sync marker to the end of
//!   its index frame — the first segment of a file also over the file's header before it;
//! * the **key id** is the first 8 bytes of SHA-512 of the public key: a verifier tells
//!   "signed by another key" from "altered";
//! * the **link** is the first 16 bytes of SHA-512 of the previous segment's signature (the
//!   previous file's last segment for a file's first), all zero where a chain starts;
//! * the **signature** is Ed25519 (RFC 8032, pure) over
//!   `"dash2sim segment v1" · key id · link · digest`, a 107-byte message any Ed25519
//!   library verifies.
//!
//! A [`Sealer`] signs as a [`super::Writer`] writes (the digest is kept as the bytes go into
//! its buffer, so nothing is read back); [`SealCheck`] judges each segment from the
//! [`super::Event`]s of a [`super::Decoder`], which keeps the digests of what it reads.
//!
//! Ed25519 comes from `salty`, written for microcontrollers: 10 KB of flash for signing and
//! its own SHA-512 (`docs/dependencies.md`).

use salty::{Keypair, PublicKey, Sha512, Signature};

/// Kind code of the signature trailer (structural, like the segment and index frames).
pub const SIGNATURE: u8 = 0x03;
/// Trailer payload length, bytes.
pub const TRAILER_LEN: usize = 1 + 8 + 16 + 64;
/// The trailer's format byte.
const FORMAT: u8 = 1;
/// What the signed message starts with: it names what is signed, so that a signature made
/// for something else by the same key never verifies here.
const DOMAIN: &[u8; 19] = b"dash2sim segment v1";
/// Signed message length.
const MESSAGE_LEN: usize = DOMAIN.len() + 8 + 16 + 64;

/// A segment's digest: SHA-512 of its bytes.
pub type Digest = [u8; 64];
/// Chain link: the first 16 bytes of SHA-512 of a signature.
pub type Link = [u8; 16];

/// The key id of a public key: the first 8 bytes of its SHA-512.
pub fn key_id(public: &[u8; 32]) -> [u8; 8] {
    let digest = Sha512::new().updated(public).finalize();
    let mut id = [0u8; 8];
    id.copy_from_slice(&digest[..8]);
    id
}

/// The link a segment signed with `signature` hands to the next one.
pub fn link_of(signature: &[u8; 64]) -> Link {
    let digest = Sha512::new().updated(signature).finalize();
    let mut link = [0u8; 16];
    link.copy_from_slice(&digest[..16]);
    link
}

fn message(key_id: &[u8; 8], link: &Link, digest: &Digest) -> [u8; MESSAGE_LEN] {
    let mut m = [0u8; MESSAGE_LEN];
    let (domain, rest) = m.split_at_mut(DOMAIN.len());
    domain.copy_from_slice(DOMAIN);
    let (id, rest) = rest.split_at_mut(8);
    id.copy_from_slice(key_id);
    let (l, d) = rest.split_at_mut(16);
    l.copy_from_slice(link);
    d.copy_from_slice(digest);
    m
}

/// A decoded signature trailer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trailer {
    /// Key id of the key that signed.
    pub key_id: [u8; 8],
    /// Link to the previous segment's signature (zero: the chain starts here).
    pub link: Link,
    /// The Ed25519 signature.
    pub signature: [u8; 64],
}

impl Trailer {
    /// The trailer in a frame's payload; `None` when it is not one (another length or
    /// format).
    pub fn decode(payload: &[u8]) -> Option<Trailer> {
        let bytes: &[u8; TRAILER_LEN] = payload.try_into().ok()?;
        let (format, rest) = bytes.split_first()?;
        if *format != FORMAT {
            return None;
        }
        let (key_id, rest) = rest.split_at(8);
        let (link, signature) = rest.split_at(16);
        Some(Trailer {
            key_id: key_id.try_into().ok()?,
            link: link.try_into().ok()?,
            signature: signature.try_into().ok()?,
        })
    }

    /// The payload bytes.
    pub fn encode(&self) -> [u8; TRAILER_LEN] {
        let mut p = [0u8; TRAILER_LEN];
        p[0] = FORMAT;
        p[1..9].copy_from_slice(&self.key_id);
        p[9..25].copy_from_slice(&self.link);
        p[25..].copy_from_slice(&self.signature);
        p
    }
}

/// The device's signing key and the state of its chain: what a [`super::Writer`] signs with.
/// Kept across the files of a recording ([`super::Writer::take_sealer`]) so that the chain
/// runs from one file into the next.
pub struct Sealer {
    key: Keypair,
    key_id: [u8; 8],
    link: Link,
    digest: Sha512,
}

impl core::fmt::Debug for Sealer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // Never the secret.
        f.debug_struct("Sealer").field("key_id", &self.key_id).field("link", &self.link).finish_non_exhaustive()
    }
}

impl Sealer {
    /// A sealer for the key with this 32-byte seed (the Ed25519 secret key); its chain
    /// starts with the next segment.
    pub fn new(seed: &[u8; 32]) -> Sealer {
        let key = Keypair::from(seed);
        let key_id = key_id(&key.public.to_bytes());
        Sealer { key, key_id, link: [0; 16], digest: Sha512::new() }
    }

    /// The public key that verifies its signatures.
    pub fn public_key(&self) -> [u8; 32] {
        self.key.public.to_bytes()
    }

    /// Start a segment's digest.
    pub(super) fn begin(&mut self) {
        self.digest = Sha512::new();
    }

    /// Bytes of the segment, in file order.
    pub(super) fn absorb(&mut self, bytes: &[u8]) {
        self.digest.update(bytes);
    }

    /// The segment is complete: its trailer; the chain moves on to it.
    pub(super) fn seal(&mut self) -> Trailer {
        let digest = core::mem::take(&mut self.digest).finalize();
        let signature = self.key.sign(&message(&self.key_id, &self.link, &digest)).to_bytes();
        let trailer = Trailer { key_id: self.key_id, link: self.link, signature };
        self.link = link_of(&signature);
        trailer
    }
}

/// The digest a reader keeps of a segment's bytes as it reads them.
#[derive(Default)]
pub(super) struct SegmentDigest {
    running: Sha512,
    /// The running digest's bytes are all the file's so far (its first segment includes the
    /// header).
    first: bool,
    /// The digest up to the end of the index frame just read.
    complete: Option<Digest>,
}

impl core::fmt::Debug for SegmentDigest {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SegmentDigest").field("complete", &self.complete.is_some()).finish_non_exhaustive()
    }
}

impl Clone for SegmentDigest {
    /// A clone starts its running digest afresh (`salty`'s is not `Clone`): a cloned decoder
    /// judges signatures from its next segment on.
    fn clone(&self) -> Self {
        SegmentDigest { running: Sha512::new(), first: false, complete: self.complete }
    }
}

impl SegmentDigest {
    pub(super) fn new() -> Self {
        SegmentDigest { running: Sha512::new(), first: true, complete: None }
    }

    /// Bytes read (every byte of the file, once, in order).
    pub(super) fn absorb(&mut self, bytes: &[u8]) {
        self.running.update(bytes);
    }

    /// A sync marker starts: a new segment's digest (the first keeps the header).
    pub(super) fn segment_starts(&mut self) {
        if !core::mem::take(&mut self.first) {
            self.running = Sha512::new();
        }
        self.complete = None;
    }

    /// The index frame has been read: the segment's digest is complete.
    pub(super) fn index_read(&mut self) {
        self.complete = Some(core::mem::take(&mut self.running).finalize());
    }

    /// Any other frame: a trailer must follow the index directly.
    pub(super) fn other_frame(&mut self) {
        self.complete = None;
    }

    /// The digest a trailer read now signs, if one is complete.
    pub(super) fn take(&mut self) -> Option<Digest> {
        self.complete.take()
    }
}

/// How a segment's signature stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Seal {
    /// Signed by the key, unaltered, and it follows the segment before it.
    Valid,
    /// Signed and unaltered; a chain starts here (a new recording).
    ChainStart,
    /// Signed and unaltered; the first segment checked, and it follows one not given (a file
    /// deleted by loop recording, or not handed to the check).
    Continues,
    /// Signed and unaltered, but it does not follow the segment before it: a segment between
    /// them was removed, or segments were reordered.
    ChainBroken,
    /// Signed by another key (its key id).
    OtherKey([u8; 8]),
    /// The signature does not match the bytes: the segment was altered or damaged.
    BadSignature,
    /// No signature: a segment written without a key, or cut off before its end (a power
    /// cut).
    Unsigned,
}

impl Seal {
    /// Whether the segment is trustworthy on its own terms: signed by the key and unaltered
    /// (a chain start or a continuation included; a broken chain, another key, altered bytes
    /// or no signature are not).
    pub fn is_trusted(self) -> bool {
        matches!(self, Seal::Valid | Seal::ChainStart | Seal::Continues)
    }

    /// How `inspect` names it.
    pub fn name(self) -> &'static str {
        match self {
            Seal::Valid => "ok",
            Seal::ChainStart => "ok (chain starts)",
            Seal::Continues => "ok (continues a segment not given)",
            Seal::ChainBroken => "chain broken",
            Seal::OtherKey(_) => "signed by another key",
            Seal::BadSignature => "bad signature",
            Seal::Unsigned => "unsigned",
        }
    }
}

/// Why a public key was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BadPublicKey;

impl core::fmt::Display for BadPublicKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("not an Ed25519 public key (32 bytes that are not a curve point)")
    }
}

impl core::error::Error for BadPublicKey {}

/// Judges the segments of one log, or of a folder's files in order, against a public key:
/// feed it the decoder's events ([`SealCheck::on_event`]) and the end of each file
/// ([`SealCheck::end_of_file`]); it reports each segment once, with its sequence number.
#[derive(Debug)]
pub struct SealCheck {
    public: PublicKey,
    key_id: [u8; 8],
    /// The link the next segment should carry; `None` before the first signed segment.
    expected: Option<Link>,
    /// The segment being read, not yet judged (its sequence number).
    open: Option<u64>,
    /// The last segment seen.
    last: Option<u64>,
}

impl SealCheck {
    /// A check against this public key.
    pub fn new(public: &[u8; 32]) -> Result<SealCheck, BadPublicKey> {
        let key = PublicKey::try_from(public).map_err(|_| BadPublicKey)?;
        Ok(SealCheck { public: key, key_id: key_id(public), expected: None, open: None, last: None })
    }

    /// One decoder event; a segment's verdict when one is decided (a trailer read, or a
    /// segment that started before the previous one was signed).
    pub fn on_event(&mut self, event: &super::Event) -> Option<(u64, Seal)> {
        match event {
            super::Event::Segment { seq, .. } => {
                self.last = Some(*seq);
                self.open.replace(*seq).map(|s| (s, Seal::Unsigned))
            }
            super::Event::Signature { trailer, digest } => {
                // A segment whose start frame was damaged is still judged (and fails): it
                // takes the number after the last one seen.
                let seq = self.open.take().unwrap_or_else(|| self.last.map_or(0, |s| s.wrapping_add(1)));
                self.last = Some(seq);
                Some((seq, self.judge(trailer, digest.as_ref())))
            }
            _ => None,
        }
    }

    /// The segments before the next one are not given (a file deleted by loop recording):
    /// the next signed segment is judged as the first, [`Seal::Continues`].
    pub fn forget_chain(&mut self) {
        self.expected = None;
    }

    /// The file ended: its last segment, if it was never signed.
    pub fn end_of_file(&mut self) -> Option<(u64, Seal)> {
        self.open.take().map(|s| (s, Seal::Unsigned))
    }

    fn judge(&mut self, trailer: &Trailer, digest: Option<&Digest>) -> Seal {
        // The next segment links to this one whatever this one's verdict: a segment is
        // reported once, not again as a broken chain in the one after it.
        let expected = self.expected.replace(link_of(&trailer.signature));
        if trailer.key_id != self.key_id {
            return Seal::OtherKey(trailer.key_id);
        }
        let Some(digest) = digest else { return Seal::BadSignature };
        let signature = Signature::from(&trailer.signature);
        if self.public.verify(&message(&trailer.key_id, &trailer.link, digest), &signature).is_err() {
            return Seal::BadSignature;
        }
        match expected {
            _ if trailer.link == [0; 16] => Seal::ChainStart,
            None => Seal::Continues,
            Some(link) if link == trailer.link => Seal::Valid,
            Some(_) => Seal::ChainBroken,
        }
    }
}

#[cfg(test)]
#[path = "signature_tests.rs"]
mod tests;
