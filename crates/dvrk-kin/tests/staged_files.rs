//! What a SIGINT/SIGTERM handler does with the staged outputs of the process: removes them all
//! (alone in its binary: the registry is process-wide).

use dvrk_kin::atomic::{remove_all_staged, Staged};

#[test]
fn a_signal_handler_removes_every_staged_file() {
    let dir = tempfile::tempdir().unwrap();
    let a = Staged::write(&dir.path().join("a.mcap"), b"a").unwrap();
    let (b, _file) = Staged::create(&dir.path().join("b.png")).unwrap();
    assert!(a.temp().exists() && b.temp().exists());
    assert_eq!(remove_all_staged(), 2);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "nothing left behind");
    // Dropping them afterwards is harmless.
    drop((a, b));
    assert_eq!(remove_all_staged(), 0);
}
