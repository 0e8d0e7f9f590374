//! Reading and writing users' files: text inputs refused with a reason (devices, FIFOs, long
//! lines, NUL bytes, deep nesting), outputs staged and committed all at once, never onto an input.

use dvrk_kin::atomic::{check_outputs, commit_all, Staged};
use dvrk_kin::nesting::{json_depth, too_deep, xml_depth};
use dvrk_kin::text_file::{excerpt, read_recording_text, read_text};
use std::path::Path;


#[test]
fn excerpts_are_cut_at_characters() {
    assert_eq!(excerpt("abc", 5), "abc");
    assert_eq!(excerpt("αβγδ", 2), "αβ…");
}

#[cfg(unix)]
#[test]
fn devices_and_fifos_are_refused_and_long_lines_named() {
    let e = read_text(Path::new("/dev/zero")).unwrap_err().to_string();
    assert!(e.contains("/dev/zero") && e.contains("a character device"), "{e}");
    let dir = std::env::temp_dir().join(format!("dvrk-text-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("f");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let e = read_recording_text(&fifo, 1 << 20, 100).unwrap_err().to_string();
    assert!(e.contains("a FIFO"), "{e}");
    let long = dir.join("long.csv");
    std::fs::write(&long, format!("a,b\n1,2\n{}\n", "x".repeat(500))).unwrap();
    let e = read_recording_text(&long, 1 << 20, 100).unwrap_err().to_string();
    assert!(e.contains("line 3 is longer than 100 bytes"), "{e}");
    std::fs::write(&long, b"a,b\n\0\0").unwrap();
    let e = read_recording_text(&long, 1 << 20, 100).unwrap_err().to_string();
    assert!(e.contains("NUL byte at byte 4 (line 2)"), "{e}");
    std::fs::write(&long, "a,b\n1,2\n").unwrap();
    assert_eq!(read_recording_text(&long, 1 << 20, 100).unwrap(), "a,b\n1,2\n");
    let e = read_recording_text(&long, 4, 100).unwrap_err().to_string();
    assert!(e.contains("at most 4 bytes"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}


#[test]
fn staged_files_appear_only_on_commit_and_vanish_when_dropped() {
    let dir = std::env::temp_dir().join(format!("dvrk-atomic-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (a, b) = (dir.join("a.txt"), dir.join("b.txt"));
    std::fs::write(&a, "old").unwrap();
    let sa = Staged::write(&a, b"new a").unwrap();
    let sb = Staged::write(&b, b"new b").unwrap();
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
    assert!(sa.temp().exists() && !b.exists());
    drop(sb);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2, "b's temporary file is gone");
    commit_all(vec![sa]).unwrap();
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&a).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode & 0o600, 0o600, "{mode:o}");
        assert_eq!(mode & 0o044, 0o044 & !umask_of(&dir), "{mode:o}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The umask's bits, read off a file created with 0o644.
#[cfg(unix)]
fn umask_of(dir: &Path) -> u32 {
    use std::os::unix::fs::PermissionsExt;
    let p = dir.join("umask");
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create(true);
    std::os::unix::fs::OpenOptionsExt::mode(&mut o, 0o644);
    drop(o.open(&p).unwrap());
    let m = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
    std::fs::remove_file(&p).unwrap();
    0o644 & !m
}

#[test]
fn outputs_clashing_with_inputs_or_each_other_are_refused() {
    let dir = std::env::temp_dir().join(format!("dvrk-outputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = dir.join("in.csv");
    std::fs::write(&input, "x").unwrap();
    let dotted = dir.join(".").join("in.csv");
    let e = check_outputs(&[("--input", &input)], &[("--output", &dotted)]).unwrap_err().to_string();
    assert!(e.contains("--output: is the input --input") && e.contains("never overwrites an input"), "{e}");
    let (a, b) = (dir.join("a.json"), dir.join("a.json"));
    let e = check_outputs(&[], &[("--report", &a), ("-o", &b)]).unwrap_err().to_string();
    assert!(e.contains("-o: is also the output --report"), "{e}");
    let e = check_outputs(&[], &[("--out", &dir.join("no/such/x.mcap"))]).unwrap_err().to_string();
    assert!(e.contains("does not exist (outputs never create directories)"), "{e}");
    let e = check_outputs(&[], &[("--out", &dir)]).unwrap_err().to_string();
    assert!(e.contains("is a directory"), "{e}");
    #[cfg(unix)]
    {
        let link = dir.join("link.csv");
        std::fs::hard_link(&input, &link).unwrap();
        assert!(check_outputs(&[("--input", &input)], &[("--output", &link)]).is_err());
        // A symbolic link to the input, and a path through a symlinked directory.
        let sym = dir.join("sym.csv");
        std::os::unix::fs::symlink(&input, &sym).unwrap();
        let e = check_outputs(&[("--input", &input)], &[("--output", &sym)]).unwrap_err().to_string();
        assert!(e.contains("is the input --input"), "{e}");
        let sub = dir.join("sub");
        std::os::unix::fs::symlink(&dir, &sub).unwrap();
        assert!(check_outputs(&[("--input", &input)], &[("--output", &sub.join("in.csv"))]).is_err());
    }
    check_outputs(&[("--input", &input)], &[("--output", &dir.join("out.csv")), ("--plot", &dir.join("p.png"))]).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}


#[test]
fn json_depth_skips_strings_and_comments() {
    assert_eq!(json_depth(r#"{"a": [1, {"b": "[[[["}], /* {{{ */ "c": 2 // [[[
    }"#), 3);
    assert_eq!(json_depth(&format!("{}{}", "[".repeat(30000), "]".repeat(30000))), 30000);
    assert_eq!(json_depth(r#"{'q': "\"[", "x": []}"#), 2);
}

#[test]
fn xml_depth_counts_elements_only() {
    let urdf = r#"<?xml version="1.0"?><!-- <a><a> --><robot name="r"><link name="a/>"><visual/></link><joint name="j"><parent link="a"/></joint></robot>"#;
    assert_eq!(xml_depth(urdf), 2);
    let deep = format!("<robot>{}{}</robot>", "<a>".repeat(30000), "</a>".repeat(30000));
    assert_eq!(xml_depth(&deep), 30001);
    assert!(too_deep(30001).unwrap().contains("nested 30001 levels deep"));
    assert!(too_deep(5).is_none());
}
