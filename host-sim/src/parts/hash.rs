//! The hashes that tie a part to what made it and to what it holds: SHA-256 as
//! lowercase hex, of a file's bytes, of a part's specification after its machine
//! file's hash, and of a whole part with its own hash field empty.

use serde::Serialize;
use sha2::{Digest, Sha256};

/// SHA-256 of `bytes`, lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// SHA-256 of `part` as compact JSON with its own hash field emptied by `unseal`
/// (a part's `part_sha256`: tune's and calibrate's parts).
pub fn unsealed_sha256<T: Serialize + Clone>(part: &T, unseal: impl FnOnce(&mut T)) -> String {
    let mut unsealed = part.clone();
    unseal(&mut unsealed);
    sha256_hex(&serde_json::to_vec(&unsealed).unwrap_or_default())
}

/// A part's specification hash, a sweep's `sweep_sha256` and a fit's
/// `fit_sha256` alike: SHA-256 of the machine file's hash (64 lowercase hex
/// digits), a line feed, and `spec` as compact JSON.
pub fn spec_sha256<T: Serialize>(machine_sha256: &str, spec: &T) -> String {
    let mut bytes = format!("{machine_sha256}\n").into_bytes();
    bytes.extend(serde_json::to_vec(spec).unwrap_or_default());
    sha256_hex(&bytes)
}
