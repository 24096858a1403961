//! The size of granval's public surface, measured from src/ and held under a ceiling
//! (docs/architecture.md, "The public interface"). No tool beyond this file: the counter
//! reads the source text.
//!
//! What counts as one public item:
//! - an item declared `pub` (not `pub(crate)`, `pub(super)`, `pub(in …)`) of kind `fn`
//!   (with any `const`/`async`/`unsafe`/`extern` qualifier), `struct`, `enum`, `union`,
//!   `trait`, `type`, `const` or `static`;
//! - each name a `pub use` re-exports (`pub use a::{B, C as D};` is two; a glob `*` is one);
//! - a `pub` method or associated item inside an `impl` block (of any type: the counter
//!   does not resolve whether the type itself is public, so a `pub` method of a
//!   `pub(crate)` type still counts — an overcount that a later step removes by
//!   downgrading the method too);
//!
//! and only where it is reachable from the crate root: in lib.rs, in modules declared
//! `pub mod` (file or inline) whose parents are all reachable, and in `impl` blocks at
//! such a scope. Not counted: modules themselves (they are namespaces; a `pub mod` only
//! makes its contents reachable), struct fields, enum variants, trait members, items
//! inside function bodies, items under `#[cfg(test)]` (module or item), items generated
//! by macros, `#[macro_export]` macros, and anything inside comments or string, raw
//! string and char literals (stripped before parsing).
//!
//! The ceiling is a ratchet: lowering it is welcome whenever the count falls; raising it
//! needs a reason written in docs/architecture.md.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// The public items at the end of the last narrowing step (see docs/architecture.md).
const CEILING: usize = 791;

/// Source text with comments, string literals and char literals blanked to spaces
/// (newlines kept, so line numbers survive). Lifetimes (`'a`) are kept.
fn strip(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |ch: char, out: &mut String| out.push(if ch == '\n' { '\n' } else { ' ' });
    let ident = |ch: char| ch.is_alphanumeric() || ch == '_';
    let mut i = 0;
    while i < c.len() {
        let prev_ident = i > 0 && ident(c[i - 1]);
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(c[i], &mut out);
                    i += 1;
                }
            }
        } else if !prev_ident && (c[i] == 'r' || (c[i] == 'b' && c.get(i + 1) == Some(&'r'))) && {
            let mut j = i + if c[i] == 'b' { 2 } else { 1 };
            while c.get(j) == Some(&'#') {
                j += 1;
            }
            c.get(j) == Some(&'"')
        } {
            // Raw string: r"…", r#"…"#, br#"…"#.
            let mut j = i + if c[i] == 'b' { 2 } else { 1 };
            let mut hashes = 0;
            while c[j] == '#' {
                hashes += 1;
                j += 1;
            }
            j += 1;
            while j < c.len() {
                if c[j] == '"' && (0..hashes).all(|h| c.get(j + 1 + h) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            for &ch in &c[i..j.min(c.len())] {
                blank(ch, &mut out);
            }
            i = j;
        } else if c[i] == '"' {
            let mut j = i + 1;
            while j < c.len() && c[j] != '"' {
                j += if c[j] == '\\' { 2 } else { 1 };
            }
            for &ch in &c[i..(j + 1).min(c.len())] {
                blank(ch, &mut out);
            }
            i = j + 1;
        } else if c[i] == '\'' && (!prev_ident || (c[i - 1] == 'b' && (i < 2 || !ident(c[i - 2]))))
        {
            // A char literal ('x', '\n', '\u{7f}') or a lifetime ('a, kept).
            let end = if c.get(i + 1) == Some(&'\\') {
                (i + 2..c.len()).find(|&j| c[j] == '\'')
            } else if c.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(e) => {
                    for &ch in &c[i..=e] {
                        blank(ch, &mut out);
                    }
                    i = e + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// Tokens: identifiers/numbers as words, every other non-space char on its own.
fn tokens(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    for ch in code.chars() {
        if ch.is_alphanumeric() || ch == '_' {
            word.push(ch);
            continue;
        }
        if !word.is_empty() {
            out.push(std::mem::take(&mut word));
        }
        if !ch.is_whitespace() {
            out.push(ch.to_string());
        }
    }
    if !word.is_empty() {
        out.push(word);
    }
    out
}

/// An item header (the tokens since the previous `;`, `{` or `}`) with its outer
/// attributes split off: (is `#[cfg(test)]`, the rest).
fn split_attrs(h: &[String]) -> (bool, &[String]) {
    let mut i = 0;
    let mut cfg_test = false;
    while i + 1 < h.len() && h[i] == "#" && (h[i + 1] == "[" || h[i + 1] == "!") {
        let mut depth = 0;
        let start = if h[i + 1] == "!" { i + 2 } else { i + 1 };
        let mut j = start;
        while j < h.len() {
            match h[j].as_str() {
                "[" => depth += 1,
                "]" => {
                    depth -= 1;
                    if depth == 0 {
                        break;
                    }
                }
                _ => {}
            }
            j += 1;
        }
        let attr: Vec<&str> = h[start..=j.min(h.len() - 1)]
            .iter()
            .map(String::as_str)
            .collect();
        if attr.starts_with(&["[", "cfg", "(", "test", ")", "]"]) {
            cfg_test = true;
        }
        i = j + 1;
    }
    (cfg_test, &h[i.min(h.len())..])
}

/// Whether a header is a `use` declaration (whose `{…}` is a name list, not a block).
fn is_use(h: &[String]) -> bool {
    let (_, h) = split_attrs(h);
    let i = match (h.first().map(String::as_str), h.get(1).map(String::as_str)) {
        (Some("pub"), Some("(")) => h.iter().position(|t| t == ")").map_or(h.len(), |p| p + 1),
        (Some("pub"), _) => 1,
        _ => 0,
    };
    h.get(i).is_some_and(|t| t == "use")
}

/// What an item header declares: (public item kind or None, is `pub`, names for `pub use`).
#[derive(Debug, PartialEq)]
enum Header {
    /// A `pub` item that counts, with its name(s).
    Item(Vec<String>),
    /// `mod NAME` with its visibility (true: plain `pub`).
    Mod(String, bool),
    Impl,
    Other,
}

fn classify(h: &[String]) -> (bool, Header) {
    let (cfg_test, h) = split_attrs(h);
    let w = |i: usize| h.get(i).map(String::as_str).unwrap_or("");
    if w(0) == "impl" || (w(0) == "unsafe" && w(1) == "impl") {
        return (cfg_test, Header::Impl);
    }
    let (public, mut i) = match (w(0), w(1)) {
        ("pub", "(") => (
            false,
            h.iter().position(|t| t == ")").map_or(h.len(), |p| p + 1),
        ),
        ("pub", _) => (true, 1),
        _ => (false, 0),
    };
    if w(i) == "mod" {
        return (cfg_test, Header::Mod(w(i + 1).to_string(), public));
    }
    if !public {
        return (cfg_test, Header::Other);
    }
    if w(i) == "use" {
        let rest = &h[i + 1..];
        let mut names = Vec::new();
        for (k, t) in rest.iter().enumerate() {
            let next = rest.get(k + 1).map(String::as_str).unwrap_or("");
            let is_word = t.chars().all(|ch| ch.is_alphanumeric() || ch == '_');
            if t == "*" || (is_word && t != "as" && next != ":" && next != "as") {
                names.push(t.clone());
            }
        }
        return (cfg_test, Header::Item(names));
    }
    // Qualifiers before the kind: `pub const fn`, `pub unsafe extern "C" fn`, ….
    while matches!(w(i), "const" | "async" | "unsafe" | "extern") && w(i + 1) != ":" {
        if w(i) == "const" && w(i + 1) != "fn" && w(i + 1) != "unsafe" {
            break;
        }
        i += 1;
    }
    match w(i) {
        "fn" | "struct" | "enum" | "union" | "trait" | "type" | "const" | "static" => {
            let name = if w(i + 1) == "mut" {
                w(i + 2)
            } else {
                w(i + 1)
            };
            (cfg_test, Header::Item(vec![name.to_string()]))
        }
        _ => (cfg_test, Header::Other),
    }
}

/// The public items of the crate whose files are `files` (path relative to src/, e.g.
/// `lib.rs`, `a/mod.rs`, `a/b.rs` → text), as (module path, item name).
fn public_items(files: &HashMap<PathBuf, String>) -> Vec<(String, String)> {
    let mut out = Vec::new();
    walk(files, Path::new("lib.rs"), Path::new(""), "crate", &mut out);
    out
}

/// Counts one reachable file. `dir` is where its child modules live.
fn walk(
    files: &HashMap<PathBuf, String>,
    file: &Path,
    dir: &Path,
    module: &str,
    out: &mut Vec<(String, String)>,
) {
    let Some(text) = files.get(file) else {
        return;
    };
    let toks = tokens(&strip(text));
    // Block stack: (counts?, module path, child dir).
    let mut stack: Vec<(bool, String, PathBuf)> = vec![(true, module.to_string(), dir.into())];
    let mut header: Vec<String> = Vec::new();
    let mut nest = 0i32; // () and [] depth inside a header, and {} inside a `use`
    for t in toks {
        match t.as_str() {
            "(" | "[" => nest += 1,
            ")" | "]" => nest -= 1,
            "{" if is_use(&header) => nest += 1,
            "}" if nest > 0 && is_use(&header) => nest -= 1,
            _ => {}
        }
        if nest > 0 && (t == "{" || t == "}") || t == "}" && is_use(&header) {
            header.push(t);
            continue;
        }
        let end = t == "{" || t == "}" || (t == ";" && nest <= 0);
        if !end {
            header.push(t);
            continue;
        }
        let (counts, module, dir) = stack.last().cloned().unwrap();
        let (cfg_test, kind) = if t == "}" {
            (false, Header::Other)
        } else {
            classify(&header)
        };
        let live = counts && !cfg_test;
        match (&kind, t.as_str()) {
            (Header::Item(names), _) if live => {
                out.extend(names.iter().map(|n| (module.clone(), n.clone())))
            }
            (Header::Mod(name, public), ";") if live && *public => {
                let sub = dir.join(name);
                let child_mod = format!("{module}::{name}");
                let (f, d) = if files.contains_key(&dir.join(format!("{name}.rs"))) {
                    (dir.join(format!("{name}.rs")), sub.clone())
                } else {
                    (sub.join("mod.rs"), sub.clone())
                };
                walk(files, &f, &d, &child_mod, out);
            }
            _ => {}
        }
        match t.as_str() {
            "{" => {
                let block = match kind {
                    Header::Mod(name, public) => {
                        (live && public, format!("{module}::{name}"), dir.join(&name))
                    }
                    Header::Impl => (live, module.clone(), dir.clone()),
                    _ => (false, module.clone(), dir.clone()),
                };
                stack.push(block);
            }
            "}" if stack.len() > 1 => {
                stack.pop();
            }
            _ => {}
        }
        header.clear();
        nest = 0;
    }
}

fn read_src(root: &Path, dir: &Path, out: &mut HashMap<PathBuf, String>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            read_src(root, &p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            let text = std::fs::read_to_string(&p).unwrap();
            out.insert(p.strip_prefix(root).unwrap().to_path_buf(), text);
        }
    }
}

#[test]
fn public_surface_stays_under_its_ceiling() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = HashMap::new();
    read_src(&root, &root, &mut files);
    let items = public_items(&files);
    let mut by_layer: BTreeMap<String, usize> = BTreeMap::new();
    for (m, _) in &items {
        let layer = m.split("::").nth(1).unwrap_or("(root)").to_string();
        *by_layer.entry(layer).or_default() += 1;
    }
    println!("public items: {}", items.len());
    for (layer, n) in &by_layer {
        println!("  {layer:<12} {n}");
    }
    if std::env::var_os("GRANVAL_PUB_SURFACE_LIST").is_some() {
        for (m, n) in &items {
            println!("{m}::{n}");
        }
    }
    assert!(
        items.len() <= CEILING,
        "the public surface grew to {} items (ceiling {CEILING}): make the new items \
         pub(crate) unless a crate outside the library (the binary, a test, the bench) \
         needs them, or give the reason for raising the ceiling in docs/architecture.md",
        items.len()
    );
    // The real crate is counted, not an empty walk.
    assert!(by_layer.contains_key("case") && by_layer.contains_key("experiments"));
}

/// Negative control: a synthetic crate with exactly 10 public items, surrounded by
/// everything the counter must ignore.
#[test]
fn counter_counts_a_known_synthetic_crate_exactly() {
    let lib = r##"
//! pub fn in_a_doc_comment() {}
pub mod open;
mod closed;
pub(crate) mod half;
pub use open::{Alpha, Beta as B};          // 2
pub fn root_fn(x: [u8; 4]) -> u8 { x[0] }  // 1
pub(crate) fn not_me() {}
/* pub fn in_a_block_comment() {} /* nested */ pub fn still_comment() {} */
const TEXT: &str = "pub fn in_a_string() { }";
const RAW: &str = r#"pub struct InARaw; }"#;
const BRACE: char = '{';
const BYTE: u8 = b'{';
#[cfg(test)]
mod tests {
    pub fn test_helper() {}
}
#[cfg(test)]
pub fn test_only() {}
pub mod inline {
    pub const LIMIT: usize = 3;                // 1
    pub(super) fn hidden() {}
    pub struct Holder<'a> { pub field: &'a str }  // 1 (not the field)
    impl<'a> Holder<'a> {
        pub fn get(&self) -> &'a str { let _ = '}'; self.field }  // 1
        fn private(&self) {}
    }
}
"##;
    let open = r#"
pub struct Alpha;                               // 1
pub enum Beta { One, Two }                      // 1
impl Alpha {
    pub const fn new() -> Self { pub fn local_to_a_body() {} Alpha }  // 1
    pub(crate) fn internal(&self) {}
}
pub trait Shape { fn area(&self) -> f64; }      // 1 (not its member)
"#;
    let closed = "pub fn unreachable_from_root() {}\npub struct AlsoUnreachable;\n";
    let half = "pub fn behind_a_crate_module() {}\n";
    let files: HashMap<PathBuf, String> = [
        ("lib.rs", lib),
        ("open.rs", open),
        ("closed.rs", closed),
        ("half/mod.rs", half),
    ]
    .into_iter()
    .map(|(p, t)| (PathBuf::from(p), t.to_string()))
    .collect();
    let items = public_items(&files);
    let mut names: Vec<String> = items.iter().map(|(m, n)| format!("{m}::{n}")).collect();
    names.sort();
    assert_eq!(
        names,
        [
            "crate::Alpha",
            "crate::B",
            "crate::inline::Holder",
            "crate::inline::LIMIT",
            "crate::inline::get",
            "crate::open::Alpha",
            "crate::open::Beta",
            "crate::open::Shape",
            "crate::open::new",
            "crate::root_fn",
        ],
    );
    assert_eq!(items.len(), 10);
}
