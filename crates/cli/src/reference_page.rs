//! The book's command-line reference (`docs/src/reference/cli.md`), generated from the
//! parser itself: every command, its help, and every argument with its value, default and
//! allowed values. A test compares the page with the committed one and fails when it is stale.

use clap::{Arg, Command};
use std::fmt::Write;

/// The whole page for the `servo` command `cli`.
pub fn page(cli: &Command) -> String {
    let mut out = String::from(
        "# Command-line reference\n\n\
         <!-- Generated from the command-line parser by `UPDATE_REFERENCE=1 cargo test -p \
         servo-cli reference_page`; edit the doc comments in crates/cli, not this page. -->\n\n\
         Every `servo` command and flag, as `servo help COMMAND` prints them. Values are SI \
         unless a flag's name says otherwise. Exit codes: [exit codes](exit-codes.md).\n\n",
    );
    let mut commands = Vec::new();
    collect(cli, "servo", &mut commands);
    out += "| command | what it does |\n|---|---|\n";
    for (path, c) in &commands[1..] {
        let about = c.get_about().map(|a| a.to_string()).unwrap_or_default();
        let _ = writeln!(out, "| [`{path}`](#{}) | {} |", anchor(path), cell(&about));
    }
    for (path, c) in &commands[1..] {
        section(&mut out, path, c);
    }
    out
}

/// The configuration reference (`docs/src/reference/configuration.md`) from the schema of
/// `servo config --schema`.
pub fn configuration_page(schema: &serde_json::Value) -> String {
    let mut out = String::from(
        "# Configuration reference\n\n\
         <!-- Generated from the configuration types by `UPDATE_REFERENCE=1 cargo test -p \
         servo-cli reference_page`; edit their doc comments (and checks), not this page. -->\n\n\
         Every key of a run configuration (TOML; `servo config --dump` prints a whole one, \
         `servo config --schema` this as a JSON Schema). Units are SI and in each key's name. \
         *Allowed* is what a run accepts, as its refusal says it; defaults are the thesis \
         prototype's. Keys of a tagged table apply to the `kind` named beside them.\n",
    );
    let mut section = String::new();
    for k in runner::schema::key_docs(schema) {
        let top = k.key.split('.').next().unwrap_or_default().to_owned();
        if top != section {
            let _ = write!(
                out,
                "\n## `[{top}]`\n\n| key | type | default | allowed | description |\n\
                 |---|---|---|---|---|\n"
            );
            section = top;
        }
        let key = match &k.kind {
            Some((table, kind)) => format!("`{}` ({table}.kind = `{kind}`)", k.key),
            None => format!("`{}`", k.key),
        };
        let _ = writeln!(
            out,
            "| {key} | {} | {} | {} | {} |",
            k.type_text,
            k.default
                .map(|d| format!("`{}`", cell(&d)))
                .unwrap_or_default(),
            k.allowed.map(|a| cell(&a)).unwrap_or_default(),
            cell(&k.description)
        );
    }
    out
}

/// The exit-code reference (`docs/src/reference/exit-codes.md`): every way a run ends, and
/// the codes a command itself exits with.
pub fn exit_codes_page() -> String {
    let mut out = String::from(
        "# Exit codes\n\n\
         <!-- Generated from the code by `UPDATE_REFERENCE=1 cargo test -p servo-cli \
         reference_page`; edit runner::stop::EndReason and the CLI's output module, not this \
         page. -->\n\n\
         Every `servo` command ends with one of these codes (`servo --help` lists them too); a \
         run's recording names its end reason in its `end` record \
         ([recordings](recordings.md#what-a-recording-guarantees)).\n\n\
         | code | end reason | meaning |\n|---|---|---|\n",
    );
    for (code, reason, meaning) in crate::output::exit_codes() {
        let reason = if reason.is_empty() {
            reason
        } else {
            format!("`{reason}`")
        };
        let _ = writeln!(out, "| {code} | {reason} | {} |", cell(&meaning));
    }
    out += "\nWhat the loop does in each case, and which events trip it: [machine \
            protection](security.md#machine-protection) (the safe-state table); for HIL runs, \
            [the modes](../how-to/hil.md#prefixes-and-modes).\n";
    out
}

/// Every visible command under `c` with its full name, depth first.
fn collect<'a>(c: &'a Command, path: &str, out: &mut Vec<(String, &'a Command)>) {
    out.push((path.to_owned(), c));
    for sub in c.get_subcommands().filter(|s| !s.is_hide_set()) {
        collect(sub, &format!("{path} {}", sub.get_name()), out);
    }
}

fn section(out: &mut String, path: &str, c: &Command) {
    let _ = writeln!(out, "\n## `{path}`\n");
    let long = c.get_long_about().or(c.get_about()).map(|a| a.to_string());
    if let Some(text) = long {
        let _ = writeln!(out, "{}\n", text.trim());
    }
    let args: Vec<&Arg> = c
        .get_arguments()
        .filter(|a| !a.is_hide_set() && !matches!(a.get_id().as_str(), "help" | "version"))
        .collect();
    if args.is_empty() {
        return;
    }
    out.push_str("| argument | value | default | help |\n|---|---|---|---|\n");
    for a in args {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            name(a),
            cell(&value(a)),
            cell(&default(a)),
            cell(&help(a))
        );
    }
}

fn name(a: &Arg) -> String {
    match (a.get_long(), a.get_short()) {
        (Some(l), Some(s)) => format!("`-{s}`, `--{l}`"),
        (Some(l), None) => format!("`--{l}`"),
        (None, Some(s)) => format!("`-{s}`"),
        (None, None) => format!("`{}` (positional)", a.get_id().as_str().to_uppercase()),
    }
}

fn value(a: &Arg) -> String {
    if !a.get_action().takes_values() {
        return "switch".into();
    }
    let choices: Vec<String> = a
        .get_possible_values()
        .iter()
        .filter(|p| !p.is_hide_set())
        .map(|p| format!("`{}`", p.get_name()))
        .collect();
    if !choices.is_empty() {
        return choices.join(", ");
    }
    a.get_value_names()
        .map(|v| {
            v.iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_else(|| a.get_id().as_str().to_uppercase())
}

fn default(a: &Arg) -> String {
    let values: Vec<String> = a
        .get_default_values()
        .iter()
        .map(|v| v.to_string_lossy().into_owned())
        .collect();
    if values.is_empty() || !a.get_action().takes_values() {
        String::new()
    } else {
        format!("`{}`", values.join(","))
    }
}

fn help(a: &Arg) -> String {
    a.get_long_help()
        .or(a.get_help())
        .map(|h| h.to_string())
        .unwrap_or_default()
}

/// Text fit for one table cell: one line, pipes escaped.
fn cell(text: &str) -> String {
    text.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace('|', "\\|")
}

/// mdBook's anchor of a heading `` `servo run` ``.
fn anchor(path: &str) -> String {
    path.replace(' ', "-")
}
