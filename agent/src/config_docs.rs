//! The configuration file with comments: `learner config` prints every field with what it means,
//! its unit and its default, so that the file it writes explains itself. The descriptions are the
//! fields' doc comments in `RunConfig` and the structs it gathers, each with its default from
//! `RunConfig::default()`, written into [`FIELD_DOCS`] (`config_docs/fields.rs`) by
//! `agent/tests/sourcegen.rs`, which fails when the file is stale, a field has no doc comment or a
//! doc comment types a default; a test here checks that every field printed has a description.

mod fields;

pub use self::fields::FIELD_DOCS;
use crate::config::RunConfig;

/// Optional fields that are absent by default: shown commented out in their table, with a value
/// to start from.
const OPTIONAL: &[(&str, &str)] = &[("env.map", "\"Town01.xodr\""), ("env.traffic.parked_car_ahead", "10.0"), ("env.reward.clip", "1.0")];

/// What a field or table means, by dotted path (`agent.gamma`, `env.camera`).
#[must_use]
pub fn field_doc(path: &str) -> Option<&'static str> {
    FIELD_DOCS.iter().find(|(p, _)| *p == path).map(|(_, d)| *d)
}

/// `cfg` as TOML with a comment above every table and field (the same values as
/// [`RunConfig::to_toml`]: comments only).
#[must_use]
pub fn commented_toml(cfg: &RunConfig) -> String {
    let mut out = String::from(
        "# hybrid-drive run configuration (TOML). Every field is shown with its value; a file may\n\
         # set only some of them: the rest take these defaults. Units are in the comments.\n\
         # Use with `learner serve --config FILE` or `actor train --config FILE`;\n\
         # `learner config --config FILE` checks a file and prints it completed.\n\n",
    );
    let mut table = String::new();
    for line in cfg.to_toml().lines() {
        let trimmed = line.trim();
        if let Some(name) = trimmed.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
            table = name.to_owned();
            if let Some(doc) = field_doc(name) {
                comment(&mut out, doc);
            }
            out.push_str(line);
            out.push('\n');
            for (path, example) in OPTIONAL {
                if let Some(key) = path.strip_prefix(&format!("{table}.")).filter(|k| !k.contains('.'))
                    && !cfg.to_toml().contains(&format!("\n{key} = "))
                {
                    comment(&mut out, field_doc(path).unwrap_or_default());
                    out.push_str(&format!("# {key} = {example}\n"));
                }
            }
            continue;
        }
        if let Some((key, _)) = trimmed.split_once(" = ") {
            let path = if table.is_empty() { key.to_owned() } else { format!("{table}.{key}") };
            if let Some(doc) = field_doc(&path) {
                comment(&mut out, doc);
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Appends `doc` as `# ` lines of at most ~100 characters.
fn comment(out: &mut String, doc: &str) {
    let mut line = String::from("#");
    for word in doc.split_whitespace() {
        if line.len() + word.len() > 99 {
            out.push_str(&line);
            out.push('\n');
            line = String::from("#");
        }
        line.push(' ');
        line.push_str(word);
    }
    out.push_str(&line);
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every table and field of `toml` by dotted path.
    fn paths(toml: &str) -> Vec<String> {
        let mut table = String::new();
        let mut out = Vec::new();
        for line in toml.lines() {
            if let Some(name) = line.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
                table = name.to_owned();
                out.push(table.clone());
            } else if let Some((key, _)) = line.split_once(" = ") {
                out.push(if table.is_empty() { key.to_owned() } else { format!("{table}.{key}") });
            }
        }
        out
    }

    #[test]
    fn every_field_of_every_preset_is_explained_and_the_file_reads_back_the_same() {
        for name in [None, Some("paper"), Some("end-to-end"), Some("hybrid-tuned"), Some("end-to-end-tuned")] {
            let cfg = name.map_or_else(RunConfig::default, |n| RunConfig::preset(n).unwrap());
            let text = commented_toml(&cfg);
            for path in paths(&cfg.to_toml()) {
                assert!(field_doc(&path).is_some(), "no description for `{path}`: regenerate FIELD_DOCS (agent/tests/sourcegen.rs)");
            }
            assert_eq!(RunConfig::from_toml(&text, "commented").unwrap(), cfg, "{name:?}");
            assert!(text.contains("# Discount γ (default 0.99).\ngamma = "), "{text}");
            assert!(text.contains("# clip = 1.0\n") && text.contains("# parked_car_ahead = 10.0\n"), "{text}");
            assert!(text.lines().all(|l| l.chars().count() <= 110), "a line is too long");
        }
    }

    #[test]
    fn every_optional_example_is_a_described_field_absent_by_default() {
        let defaults = RunConfig::default().to_toml();
        for (path, _) in OPTIONAL {
            assert!(field_doc(path).is_some(), "OPTIONAL names `{path}`, which is no field");
            assert!(!paths(&defaults).contains(&(*path).to_owned()), "`{path}` is set by default: drop it from OPTIONAL");
        }
    }

    #[test]
    fn optional_fields_that_are_set_are_not_repeated_as_comments() {
        let mut cfg = RunConfig::default();
        cfg.env.reward.clip = Some(2.0);
        let text = commented_toml(&cfg);
        assert!(text.contains("\nclip = 2.0\n") && !text.contains("# clip = 1.0"), "{text}");
    }
}
