//! docs/cli.md's table of shared flags against the built binary: every flag it lists is a flag of
//! exactly the commands it names (read from each command's `--help`), and a flag listed for
//! every command is global.

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// The `--help` text of `ferrocal <path>`.
fn help(path: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrocal")).args(path).arg("--help").output().unwrap();
    assert!(out.status.success(), "ferrocal {} --help failed", path.join(" "));
    String::from_utf8(out.stdout).unwrap()
}

/// The subcommands (without `help`) and the long flags (without `--help` and `--version`) of a
/// `--help` text: the names of its `Commands:` section and the flags that open a line of its
/// option sections (descriptions are indented deeper).
fn parse_help(text: &str) -> (Vec<String>, BTreeSet<String>) {
    let (mut subs, mut flags, mut section) = (Vec::new(), BTreeSet::new(), "");
    for line in text.lines() {
        if !line.starts_with(' ') && line.ends_with(':') {
            section = line;
            continue;
        }
        let indent = line.len() - line.trim_start().len();
        if section == "Commands:" && indent == 2 {
            let name = line.split_whitespace().next().unwrap_or("").to_string();
            if name != "help" {
                subs.push(name);
            }
        } else if section != "Commands:" && indent <= 6 && line.trim_start().starts_with('-') {
            let flag = line.split([' ', ',', '=']).find(|t| t.starts_with("--")).map(|t| t.trim_start_matches("--"));
            if let Some(f) = flag.filter(|f| *f != "help" && *f != "version") {
                flags.insert(f.to_string());
            }
        }
    }
    (subs, flags)
}

/// Every command (by its path, `camera calibrate`) that takes arguments of its own, with the
/// long names of those arguments (the global ones left out).
fn commands_and_flags(global: &BTreeSet<String>) -> BTreeMap<String, BTreeSet<String>> {
    fn walk(path: &mut Vec<String>, global: &BTreeSet<String>, out: &mut BTreeMap<String, BTreeSet<String>>) {
        let args: Vec<&str> = path.iter().map(String::as_str).collect();
        let (subs, flags) = parse_help(&help(&args));
        let own: BTreeSet<String> = flags.difference(global).cloned().collect();
        if !path.is_empty() && (subs.is_empty() || !own.is_empty()) {
            out.insert(path.join(" "), own);
        }
        for s in subs {
            path.push(s);
            walk(path, global, out);
            path.pop();
        }
    }
    let mut out = BTreeMap::new();
    walk(&mut Vec::new(), global, &mut out);
    out
}

#[test]
fn the_shared_flag_table_names_exactly_the_commands_that_have_each_flag() {
    let doc = include_str!("../../docs/cli.md");
    let global = parse_help(&help(&[])).1;
    let commands = commands_and_flags(&global);
    let mut rows = 0;
    for line in doc.lines().filter(|l| l.starts_with("| `--")) {
        let cells: Vec<&str> = line.trim_matches('|').split(" | ").map(str::trim).collect();
        let flag = cells[0].trim_start_matches("`--").split([' ', '`']).next().unwrap();
        let listed = cells[cells.len() - 1];
        rows += 1;
        if listed == "every command" {
            assert!(global.contains(flag), "--{flag} is listed for every command but is not global");
            let (subs, _) = parse_help(&help(&[]));
            for s in subs {
                assert!(
                    parse_help(&help(&[&s])).1.contains(flag),
                    "--{flag} is listed for every command but `{s}` lacks it"
                );
            }
            continue;
        }
        let want: BTreeSet<String> = listed.split(", ").map(|c| c.trim_matches('`').to_string()).collect();
        for c in &want {
            assert!(commands.contains_key(c), "docs/cli.md lists `{c}` for --{flag}, but there is no such command");
        }
        let have: BTreeSet<String> =
            commands.iter().filter(|(_, f)| f.contains(flag)).map(|(c, _)| c.clone()).collect();
        assert_eq!(have, want, "--{flag}: the commands that have it (left) and docs/cli.md's list (right)");
    }
    assert!(rows >= 15, "the table has {rows} rows");
}
