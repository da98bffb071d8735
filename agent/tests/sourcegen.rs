//! Generates `agent/src/config_docs/fields.rs`, the descriptions `learner config` prints above
//! every table and field, from the `///` doc comments of `RunConfig` and the structs it gathers
//! (here and in sim-core) and, for every field, its default from `RunConfig::default()`; fails when
//! the committed file differs. The doc comments are the one source of what a field means and
//! `impl Default` of what it defaults to: a doc comment that types a default is refused.
//! Regenerate with `UPDATE_SOURCEGEN=1 cargo test -p agent --test sourcegen`.
//! (rust-analyzer's "sourcegen" tests.)

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The generated file, relative to the agent crate.
const GENERATED: &str = "src/config_docs/fields.rs";
/// The struct whose fields are the top level of the configuration file.
const ROOT: &str = "RunConfig";

/// A struct that derives `Deserialize`: its fields as the configuration file names them.
struct ConfigStruct {
    file: PathBuf,
    fields: Vec<Field>,
}

struct Field {
    /// The name in the file (`#[serde(rename)]` applied).
    key: String,
    /// The doc comment, lines joined by spaces; empty when there is none.
    doc: String,
    /// The struct name of the field's type (`Option<T>` unwrapped), if it is a plain path.
    type_name: Option<String>,
}

#[test]
fn config_field_descriptions_are_generated_from_the_doc_comments() {
    let agent = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut structs = BTreeMap::new();
    let workspace = agent.parent().expect("agent/ is in the workspace");
    for dir in [workspace.join("agent/src"), workspace.join("sim-core/src")] {
        collect(&dir, &mut structs);
    }
    let defaults: toml::Table = toml::from_str(&agent::config::RunConfig::default().to_toml()).expect("the defaults read back");
    let mut entries = Vec::new();
    walk(&structs, &defaults, ROOT, "", &mut entries);
    let text = render(&entries);
    let path = agent.join(GENERATED);
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed == text {
        return;
    }
    if std::env::var_os("UPDATE_SOURCEGEN").is_some() {
        std::fs::write(&path, &text).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
        return;
    }
    panic!(
        "{} is not what the configuration structs' doc comments give: regenerate it with \
         `UPDATE_SOURCEGEN=1 cargo test -p agent --test sourcegen` and commit it",
        path.display()
    );
}

/// Every struct deriving `Deserialize` in the `.rs` files under `dir`, by name.
fn collect(dir: &Path, out: &mut BTreeMap<String, ConfigStruct>) {
    let mut entries: Vec<_> =
        std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())).map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            collect(&path, out);
            continue;
        }
        if path.extension().is_none_or(|x| x != "rs") {
            continue;
        }
        let source = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let file = syn::parse_file(&source).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for item in file.items {
            let syn::Item::Struct(item) = item else { continue };
            if !derives_deserialize(&item.attrs) {
                continue;
            }
            let syn::Fields::Named(named) = &item.fields else { continue };
            let fields = named
                .named
                .iter()
                .filter(|f| !serde_flag(&f.attrs, "skip"))
                .map(|f| Field {
                    key: serde_rename(&f.attrs).unwrap_or_else(|| f.ident.as_ref().unwrap().to_string()),
                    doc: doc(&f.attrs),
                    type_name: type_name(&f.ty),
                })
                .collect();
            let name = item.ident.to_string();
            let previous = out.insert(name.clone(), ConfigStruct { file: path.clone(), fields });
            if let Some(previous) = previous {
                panic!("two structs named `{name}` derive Deserialize ({} and {}): rename one", previous.file.display(), path.display());
            }
        }
    }
}

/// Appends (dotted path, description with the default) for every field of `name` and, depth
/// first, of the structs they hold; `defaults` is `RunConfig::default()` as a TOML table.
fn walk(structs: &BTreeMap<String, ConfigStruct>, defaults: &toml::Table, name: &str, prefix: &str, out: &mut Vec<(String, String)>) {
    let s = &structs[name];
    for field in &s.fields {
        let path = format!("{prefix}{}", field.key);
        assert!(
            !field.doc.is_empty(),
            "`{name}::{}` ({}) has no doc comment: `learner config` prints it as the description of `{path}`; add a `///` line",
            field.key,
            s.file.display()
        );
        assert!(
            !field.doc.contains("(default") && !field.doc.contains("default)"),
            "`{name}::{}` ({}) types its default in its doc comment: drop it, the description of `{path}` gets it from \
             `RunConfig::default()`",
            field.key,
            s.file.display()
        );
        let inner = field.type_name.as_deref().filter(|t| structs.contains_key(*t));
        let doc = match default_text(&field.key, lookup(defaults, &path), inner.is_some()) {
            Some(default) => with_default(&field.doc, &default),
            None => field.doc.clone(),
        };
        out.push((path.clone(), doc));
        if let Some(inner) = inner {
            walk(structs, defaults, inner, &format!("{path}."), out);
        }
    }
}

/// The value at dotted `path` of `table`, if it is set.
fn lookup<'a>(table: &'a toml::Table, path: &str) -> Option<&'a toml::Value> {
    let (first, rest) = path.split_once('.').map_or((path, None), |(a, b)| (a, Some(b)));
    let value = table.get(first)?;
    match rest {
        None => Some(value),
        Some(rest) => lookup(value.as_table()?, rest),
    }
}

/// How the description says the default of field `key` (`default 0.99`, `default: none`): none
/// for a table other than a range (its fields say theirs).
fn default_text(key: &str, value: Option<&toml::Value>, is_table: bool) -> Option<String> {
    match value {
        None if is_table => None,
        None => Some("default: none".to_owned()),
        Some(toml::Value::Table(t)) => match (t.get("min"), t.get("max")) {
            (Some(min), Some(max)) if t.len() == 2 => Some(format!("default {}–{}", value_text(key, min), value_text(key, max))),
            _ => None,
        },
        Some(v) => Some(format!("default {}", value_text(key, v))),
    }
}

/// A value as a reader writes it: `64 MiB` for whole mebibytes of a `*_bytes` field, digits
/// grouped by threes (`100 000`), `2.5e-4`, `−1`, strings in backticks, an empty one `empty`.
fn value_text(key: &str, value: &toml::Value) -> String {
    const MIB: i64 = 1 << 20;
    match value {
        toml::Value::String(s) if s.is_empty() => "empty".to_owned(),
        toml::Value::String(s) => format!("`{s}`"),
        toml::Value::Integer(i) if key.ends_with("_bytes") && *i > 0 && i % (MIB << 10) == 0 => format!("{} GiB", i / (MIB << 10)),
        toml::Value::Integer(i) if key.ends_with("_bytes") && *i > 0 && i % MIB == 0 => format!("{} MiB", i / MIB),
        toml::Value::Integer(i) => {
            let digits = i.unsigned_abs().to_string();
            let mut grouped = String::from(if *i < 0 { "−" } else { "" });
            for (n, c) in digits.chars().enumerate() {
                if n > 0 && (digits.len() - n) % 3 == 0 {
                    grouped.push(' ');
                }
                grouped.push(c);
            }
            grouped
        }
        toml::Value::Float(f) => {
            let magnitude = if *f != 0.0 && f.abs() < 1e-3 { format!("{:e}", f.abs()) } else { format!("{}", f.abs()) };
            if *f < 0.0 { format!("−{magnitude}") } else { magnitude }
        }
        toml::Value::Boolean(b) => b.to_string(),
        toml::Value::Array(items) if items.is_empty() => "none".to_owned(),
        toml::Value::Array(items) => items.iter().map(|v| value_text(key, v)).collect::<Vec<_>>().join(", "),
        other => other.to_string(),
    }
}

/// `doc` with ` (DEFAULT)` at the end of its first sentence.
fn with_default(doc: &str, default: &str) -> String {
    let end = doc.find(". ").unwrap_or_else(|| doc.strip_suffix('.').map_or(doc.len(), str::len));
    format!("{} ({default}){}", &doc[..end], &doc[end..])
}

fn render(entries: &[(String, String)]) -> String {
    let mut out = String::from(
        "//! Generated by `agent/tests/sourcegen.rs` from the doc comments of `RunConfig` and the structs\n\
         //! it gathers: do not edit; change the doc comment and run\n\
         //! `UPDATE_SOURCEGEN=1 cargo test -p agent --test sourcegen`.\n\n\
         /// Every field and table of the configuration file by dotted path, and what it means.\n\
         #[rustfmt::skip]\n\
         pub const FIELD_DOCS: &[(&str, &str)] = &[\n",
    );
    for (path, doc) in entries {
        writeln!(out, "    ({path:?}, {doc:?}),").unwrap();
    }
    out.push_str("];\n");
    out
}

fn derives_deserialize(attrs: &[syn::Attribute]) -> bool {
    let mut found = false;
    for attr in attrs.iter().filter(|a| a.path().is_ident("derive")) {
        attr.parse_nested_meta(|m| {
            found |= m.path.segments.last().is_some_and(|s| s.ident == "Deserialize");
            Ok(())
        })
        .unwrap();
    }
    found
}

/// Whether a `#[serde(...)]` attribute holds the bare word `flag`.
fn serde_flag(attrs: &[syn::Attribute], flag: &str) -> bool {
    let mut found = false;
    serde_items(attrs, |m| {
        found |= m.path.is_ident(flag);
    });
    found
}

fn serde_rename(attrs: &[syn::Attribute]) -> Option<String> {
    let mut rename = None;
    serde_items(attrs, |m| {
        if m.path.is_ident("rename") {
            let lit: syn::LitStr = m.value().unwrap().parse().unwrap();
            rename = Some(lit.value());
        }
    });
    rename
}

/// Calls `f` on every item of the field's `#[serde(...)]` attributes, skipping their values.
fn serde_items(attrs: &[syn::Attribute], mut f: impl FnMut(&syn::meta::ParseNestedMeta)) {
    for attr in attrs.iter().filter(|a| a.path().is_ident("serde")) {
        attr.parse_nested_meta(|m| {
            assert!(!m.path.is_ident("flatten"), "#[serde(flatten)] in a configuration struct: teach agent/tests/sourcegen.rs about it");
            f(&m);
            if m.input.peek(syn::Token![=]) {
                let _: syn::Expr = m.value()?.parse()?;
            }
            Ok(())
        })
        .unwrap();
    }
}

/// The doc comment's lines, trimmed and joined by single spaces.
fn doc(attrs: &[syn::Attribute]) -> String {
    let mut lines = Vec::new();
    for attr in attrs.iter().filter(|a| a.path().is_ident("doc")) {
        if let syn::Meta::NameValue(nv) = &attr.meta
            && let syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) = &nv.value
        {
            let line = s.value();
            if !line.trim().is_empty() {
                lines.push(line.trim().to_owned());
            }
        }
    }
    lines.join(" ")
}

/// `T` of a field of type `T`, `a::b::T` or `Option<T>`.
fn type_name(ty: &syn::Type) -> Option<String> {
    let syn::Type::Path(p) = ty else { return None };
    let last = p.path.segments.last()?;
    if last.ident == "Option"
        && let syn::PathArguments::AngleBracketed(args) = &last.arguments
        && let Some(syn::GenericArgument::Type(inner)) = args.args.first()
    {
        return type_name(inner);
    }
    Some(last.ident.to_string())
}
