//! Every command of the README's Quickstart, read from the README itself and run as a user
//! would (issue 63 item 5: its `dvrk model check PSM.json --tool ...` failed on the dVRK's own
//! files). The files a command names are the real ones where the project has them (the dVRK's
//! configuration files, the WPI recordings) or made by the command that makes them (`dvrk synth`);
//! outputs go to a temporary folder; a long run is shortened and a live one given a free port and
//! an end. A command the test cannot run says why, and a new README command that it does not
//! know how to run fails it.

use crate::util::{dvrk, external, tempdir};
use std::path::Path;

/// The Quickstart's commands: the `sh` block under `## Quickstart`, comments stripped.
fn quickstart_commands() -> Vec<Vec<String>> {
    let readme = include_str!("../README.md");
    let start = readme.find("## Quickstart").expect("README has a Quickstart");
    let block = &readme[start..];
    let open = block.find("```sh\n").expect("a sh block") + 6;
    let close = open + block[open..].find("```").expect("the block ends");
    block[open..close].lines().map(|l| l.split(" #").next().unwrap_or("").split_whitespace().map(str::to_string).collect::<Vec<_>>()).filter(|w| !w.is_empty()).collect()
}

#[test]
fn every_quickstart_command_runs() {
    let dir = tempdir();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let shared = |p: &str| external(p).map(|p| p.to_string_lossy().into_owned());
    let commands = quickstart_commands();
    assert!(commands.len() >= 10, "{commands:?}");
    let mut ran = 0;
    for words in &commands {
        if words[0] == "cargo" {
            // `cargo install --path .`: the test runs the binary this build made.
            assert_eq!(words[..2], ["cargo", "install"]);
            continue;
        }
        assert_eq!(words[0], "dvrk", "{words:?}");
        let mut args: Vec<String> = Vec::new();
        let mut skip = None;
        let mut it = words[1..].iter().peekable();
        while let Some(w) = it.next() {
            let file = |name: &str| -> Option<String> {
                match name {
                    "PSM.json" | "LARGE_NEEDLE_DRIVER_400006.json" => shared(&format!("dvrk-config/{name}")),
                    "one.csv" => shared("wpi-dvrk-dynamics/psm_one_results.csv"),
                    "two.csv" => shared("wpi-dvrk-dynamics/psm_two_results.csv"),
                    _ => Some(out(name)),
                }
            };
            match w.as_str() {
                // A long run: a second is enough to show it runs.
                "--duration" => {
                    it.next();
                    args.extend(["--duration".into(), "1".into()]);
                }
                // Watched live: a free port (the test's neighbours may hold 8765).
                "--live" => args.extend(["--live".into(), "127.0.0.1:0".into()]),
                x if x.ends_with(".json") || x.ends_with(".csv") || x.ends_with(".mcap") || x.ends_with(".toml") || x.ends_with(".xml") || x.ends_with(".png") => match file(x) {
                    Some(p) => args.push(p),
                    None => skip = Some(format!("{x} is not in ../shared/data/external")),
                },
                x => args.push(x.to_string()),
            }
        }
        if let Some(why) = skip {
            eprintln!("skipped `{}`: {why}", words.join(" "));
            continue;
        }
        if words[1] == "serve" && !args.contains(&"--duration".to_string()) {
            args.extend(["--duration".into(), "0.5".into()]);
        }
        // The inputs the README's reader brings: a joint recording and a motion-capture one.
        if args.iter().any(|a| a == &out("run.mcap")) && !Path::new(&out("run.mcap")).exists() {
            let made = dvrk(&["synth", "hidden-effect", "--effect", "none", "--duration", "12", "--engine", "reduced", "-o", &out("run.mcap"), "--answer", &out("answer.json")]);
            assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
        }
        if args.iter().any(|a| a == &out("mocap.mcap")) && !Path::new(&out("mocap.mcap")).exists() {
            let made = dvrk(&["synth", "mocap", "-o", &out("mocap.mcap")]);
            assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
        }
        if args.iter().any(|a| a == &out("my-psm.toml")) && words[1] == "discrepancy" && !Path::new(&out("my-psm.toml")).exists() {
            eprintln!("skipped `{}`: my-psm.toml comes from the identify line, which was skipped", words.join(" "));
            continue;
        }
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let r = dvrk(&refs);
        assert!(r.status.success(), "`dvrk {}` failed:\n{}{}", refs.join(" "), String::from_utf8_lossy(&r.stdout), String::from_utf8_lossy(&r.stderr));
        ran += 1;
    }
    eprintln!("ran {ran} of {} Quickstart commands", commands.len());
    assert!(ran >= 7, "{ran}");
}
