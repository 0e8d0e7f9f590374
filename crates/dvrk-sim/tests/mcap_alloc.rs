//! A damaged MCAP allocates no more than its own size (issue 45, bounded input). Found by the
//! coverage-guided fuzz campaign (`tests/fuzz.rs::mcap_joint_states`, libFuzzer, session 37): a
//! channel record whose topic length field was damaged made the `mcap` crate reserve the declared
//! length (2.8 GB) before reading it; libFuzzer reported it as out of memory, a machine without
//! overcommit would abort. A counting global allocator here adds up what the read requests.

use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// An MCAP record: opcode, length (u64), body.
fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut out = vec![opcode];
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    out
}

/// An MCAP string: length (u32), bytes.
fn string(s: &[u8]) -> Vec<u8> {
    let mut out = (s.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(s);
    out
}

#[test]
fn a_damaged_string_length_allocates_nothing_like_it() {
    const MAGIC: &[u8] = b"\x89MCAP0\r\n";
    let mut header = string(b"ros2");
    header.extend(string(b"dvrk-twin test"));
    // A channel whose topic says 2.8 GB where 16 bytes follow.
    let mut channel = vec![1, 0, 0, 0];
    channel.extend_from_slice(&2_837_135_214u32.to_le_bytes());
    channel.extend_from_slice(b"/PSM1/measured_js");
    let mut file = MAGIC.to_vec();
    file.extend(record(0x01, &header));
    file.extend(record(0x04, &channel));
    file.extend(record(0x0F, &[0, 0, 0, 0]));
    file.extend(record(0x02, &[0; 20]));
    file.extend_from_slice(MAGIC);
    let path = std::path::Path::new("damaged.mcap");
    let region = Region::new(GLOBAL);
    let out = dvrk_sim::recording::for_each_mcap(&file, path, |_| Ok(()));
    let requested = region.change().bytes_allocated + region.change().bytes_reallocated.max(0) as usize;
    let err = out.expect_err("a damaged channel record is an error").to_string();
    assert!(err.contains("damaged.mcap") && err.contains("damaged"), "{err}");
    // The reader's own buffers and the error: far below the 2.8 GB the record claims.
    assert!(requested < 1 << 20, "the read requested {requested} bytes");
}
