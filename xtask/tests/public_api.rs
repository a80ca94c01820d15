//! Public-API snapshot of every library crate (`crates/*`): the stand-in for
//! `cargo semver-checks`, which needs a published baseline we do not have.
//!
//! For each crate the test parses `src/` with `syn` (following `mod` declarations from
//! `lib.rs`, private modules included, since their `pub` items are reached through
//! `pub use`), writes one line per public item — `pub fn` signatures, `pub struct` with its
//! derives, `#[non_exhaustive]` and public fields, `pub enum` with its variants, traits,
//! consts, type aliases, `pub use` re-exports, the public methods of inherent impls and the
//! trait impls — and compares it with `api/<crate>.txt`. A change fails with the diff; when
//! the change is intended, bless it and review the diff in the commit:
//!
//! ```text
//! UPDATE_API=1 cargo test -p xtask --test public_api
//! ```
//!
//! Test code (`#[cfg(test)]`) and doc comments are not part of the snapshot; bodies are not
//! either (a behaviour change is the tests' business, a signature change is this one's).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use quote::ToTokens;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask sits in the workspace root")
        .to_path_buf()
}

/// `quote`'s token text with the spaces rustfmt would not write removed.
fn tidy(tokens: &impl ToTokens) -> String {
    let mut s = tokens.to_token_stream().to_string();
    for (from, to) in [
        (" ,", ","),
        (" ;", ";"),
        (" :: ", "::"),
        (":: ", "::"),
        (" ::", "::"),
        (" : ", ": "),
        ("& ", "&"),
        (" <", "<"),
        ("< ", "<"),
        (" >", ">"),
        ("( ", "("),
        (" )", ")"),
        ("[ ", "["),
        (" ]", "]"),
        ("# [", "#["),
        (" !", "!"),
    ] {
        s = s.replace(from, to);
    }
    // `fn name (` → `fn name(`, `Foo (x)` → `Foo(x)`; `-> (A, B)` keeps its space.
    let mut out = String::with_capacity(s.len());
    let chars: Vec<char> = s.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        let word_before = i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_');
        if c == ' ' && word_before && chars.get(i + 1) == Some(&'(') {
            continue;
        }
        out.push(c);
    }
    // `->` was split by the `" >"` rule when written `- >`; `->` itself never had a space.
    out.replace("-> >", "->>")
}

fn is_pub(v: &syn::Visibility) -> bool {
    matches!(v, syn::Visibility::Public(_))
}

fn is_test_only(attrs: &[syn::Attribute]) -> bool {
    attrs
        .iter()
        .any(|a| a.path().is_ident("cfg") && tidy(&a.meta).replace(' ', "").contains("cfg(test)"))
}

/// The attributes that are part of the API: derives, `non_exhaustive`, `repr`, `cfg`,
/// `cfg_attr` (the derives of a `serde` feature), `must_use`, `serde` (the JSON form).
fn api_attrs(attrs: &[syn::Attribute]) -> String {
    let mut s = String::new();
    for a in attrs {
        let p = a.path();
        if [
            "derive",
            "non_exhaustive",
            "repr",
            "cfg",
            "cfg_attr",
            "must_use",
            "serde",
        ]
        .iter()
        .any(|n| p.is_ident(n))
        {
            s.push_str(&tidy(a));
            s.push(' ');
        }
    }
    s
}

fn fields_text(fields: &syn::Fields, only_pub: bool) -> String {
    let shown = |f: &syn::Field| !only_pub || is_pub(&f.vis);
    match fields {
        syn::Fields::Unit => String::new(),
        syn::Fields::Unnamed(u) => {
            let parts: Vec<String> = u
                .unnamed
                .iter()
                .map(|f| {
                    if shown(f) {
                        format!("{}{}", api_attrs(&f.attrs), tidy(&f.ty))
                    } else {
                        "_".into()
                    }
                })
                .collect();
            format!("({})", parts.join(", "))
        }
        syn::Fields::Named(n) => {
            let hidden = n.named.iter().filter(|f| !shown(f)).count();
            let mut parts: Vec<String> = n
                .named
                .iter()
                .filter(|f| shown(f))
                .map(|f| {
                    format!(
                        "{}{}: {}",
                        api_attrs(&f.attrs),
                        f.ident
                            .as_ref()
                            .map(ToString::to_string)
                            .unwrap_or_default(),
                        tidy(&f.ty)
                    )
                })
                .collect();
            if hidden > 0 {
                parts.push(format!("/* {hidden} private */"));
            }
            format!(" {{ {} }}", parts.join(", "))
        }
    }
}

struct Walker {
    krate: String,
    out: Vec<String>,
}

impl Walker {
    fn line(&mut self, module: &str, text: String) {
        self.out.push(format!("{module}: {text}"));
    }

    fn file(&mut self, path: &Path, module: &str, dir: &Path) {
        let src = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("{}: cannot read: {e}", path.display()));
        let file = syn::parse_file(&src)
            .unwrap_or_else(|e| panic!("{}: cannot parse: {e}", path.display()));
        self.items(&file.items, module, dir);
    }

    fn items(&mut self, items: &[syn::Item], module: &str, dir: &Path) {
        for item in items {
            self.item(item, module, dir);
        }
    }

    fn item(&mut self, item: &syn::Item, module: &str, dir: &Path) {
        use syn::Item;
        match item {
            Item::Mod(m) if !is_test_only(&m.attrs) => self.module(m, module, dir),
            Item::Fn(f) if is_pub(&f.vis) && !is_test_only(&f.attrs) => {
                self.line(
                    module,
                    format!("{}pub {}", api_attrs(&f.attrs), tidy(&f.sig)),
                );
            }
            Item::Struct(s) if is_pub(&s.vis) && !is_test_only(&s.attrs) => {
                let g = &s.generics;
                let wc = g.where_clause.as_ref().map(|w| format!(" {}", tidy(w)));
                self.line(
                    module,
                    format!(
                        "{}pub struct {}{}{}{}",
                        api_attrs(&s.attrs),
                        s.ident,
                        tidy(g),
                        wc.unwrap_or_default(),
                        fields_text(&s.fields, true)
                    ),
                );
            }
            Item::Enum(e) if is_pub(&e.vis) && !is_test_only(&e.attrs) => {
                self.line(module, enum_text(e));
            }
            Item::Trait(t) if is_pub(&t.vis) && !is_test_only(&t.attrs) => {
                self.line(module, trait_text(t));
            }
            Item::Const(c) if is_pub(&c.vis) && !is_test_only(&c.attrs) => {
                self.line(module, format!("pub const {}: {}", c.ident, tidy(&c.ty)));
            }
            Item::Static(s) if is_pub(&s.vis) && !is_test_only(&s.attrs) => {
                self.line(module, format!("pub static {}: {}", s.ident, tidy(&s.ty)));
            }
            Item::Type(t) if is_pub(&t.vis) && !is_test_only(&t.attrs) => {
                let mut t = t.clone();
                t.attrs.clear();
                self.line(module, tidy(&t));
            }
            Item::Use(u) if is_pub(&u.vis) && !is_test_only(&u.attrs) => {
                let mut u = u.clone();
                u.attrs.clear();
                self.line(module, tidy(&u));
            }
            Item::Macro(m) if m.attrs.iter().any(|a| a.path().is_ident("macro_export")) => {
                let name = m
                    .ident
                    .as_ref()
                    .map(ToString::to_string)
                    .unwrap_or_default();
                self.line(&self.krate.clone(), format!("macro_rules! {name}"));
            }
            Item::Impl(i) if !is_test_only(&i.attrs) => self.impl_block(i, module),
            _ => {}
        }
    }

    /// A module: its `pub mod` line, then its items (inline, or from its file).
    fn module(&mut self, m: &syn::ItemMod, module: &str, dir: &Path) {
        let name = m.ident.to_string();
        let child = format!("{module}::{name}");
        if is_pub(&m.vis) {
            self.line(module, format!("{}pub mod {name}", api_attrs(&m.attrs)));
        }
        match &m.content {
            Some((_, inner)) => self.items(inner, &child, &dir.join(&name)),
            None => {
                let flat = dir.join(format!("{name}.rs"));
                let nested = dir.join(&name).join("mod.rs");
                let path = if flat.exists() { flat } else { nested };
                self.file(&path, &child, &dir.join(&name));
            }
        }
    }

    fn impl_block(&mut self, i: &syn::ItemImpl, module: &str) {
        let head = format!(
            "{}impl{} {}{}",
            if i.unsafety.is_some() { "unsafe " } else { "" },
            tidy(&i.generics),
            i.trait_
                .as_ref()
                .map(|(bang, path, _)| {
                    format!(
                        "{}{} for ",
                        if bang.is_some() { "!" } else { "" },
                        tidy(path)
                    )
                })
                .unwrap_or_default(),
            tidy(&i.self_ty)
        );
        if i.trait_.is_some() {
            self.line(module, head);
            return;
        }
        for ii in &i.items {
            match ii {
                syn::ImplItem::Fn(f) if is_pub(&f.vis) && !is_test_only(&f.attrs) => {
                    self.line(
                        module,
                        format!("{head} {{ {}pub {} }}", api_attrs(&f.attrs), tidy(&f.sig)),
                    );
                }
                syn::ImplItem::Const(c) if is_pub(&c.vis) => {
                    self.line(
                        module,
                        format!("{head} {{ pub const {}: {} }}", c.ident, tidy(&c.ty)),
                    );
                }
                _ => {}
            }
        }
    }
}

/// The snapshot of the crate in `dir` (its `src/lib.rs` and the modules it declares).
fn snapshot(dir: &Path, krate: &str) -> String {
    let mut w = Walker {
        krate: krate.to_string(),
        out: Vec::new(),
    };
    let src = dir.join("src");
    w.file(&src.join("lib.rs"), krate, &src);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Public API of {krate} (xtask/tests/public_api.rs; bless with UPDATE_API=1)"
    );
    for line in &w.out {
        let _ = writeln!(s, "{line}");
    }
    s
}

/// The first lines where `want` and `got` differ, as `-`/`+` lines (order-aware).
fn diff(want: &str, got: &str) -> String {
    let w: Vec<&str> = want.lines().collect();
    let g: Vec<&str> = got.lines().collect();
    let ws: std::collections::BTreeSet<&str> = w.iter().copied().collect();
    let gs: std::collections::BTreeSet<&str> = g.iter().copied().collect();
    let mut s = String::new();
    for l in w.iter().filter(|l| !gs.contains(*l)).take(40) {
        let _ = writeln!(s, "- {l}");
    }
    for l in g.iter().filter(|l| !ws.contains(*l)).take(40) {
        let _ = writeln!(s, "+ {l}");
    }
    if s.is_empty() {
        s.push_str("(the same lines in another order)\n");
    }
    s
}

#[test]
fn public_api_matches_the_snapshots() {
    let root = workspace();
    let update = std::env::var_os("UPDATE_API").is_some();
    let mut crates: Vec<PathBuf> = std::fs::read_dir(root.join("crates"))
        .expect("crates/ is readable")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("src/lib.rs").exists())
        .collect();
    crates.sort();
    assert!(!crates.is_empty(), "no library crate under crates/");
    let mut failures = String::new();
    for dir in &crates {
        let name = dir
            .file_name()
            .and_then(|n| n.to_str())
            .expect("a crate directory has a UTF-8 name")
            .to_string();
        let got = snapshot(dir, &name.replace('-', "_"));
        let file = root.join("api").join(format!("{name}.txt"));
        if update {
            std::fs::create_dir_all(root.join("api")).expect("api/ can be created");
            std::fs::write(&file, &got).expect("the snapshot can be written");
            continue;
        }
        match std::fs::read_to_string(&file) {
            Ok(want) if want == got => {}
            Ok(want) => {
                let _ = writeln!(
                    failures,
                    "\n{name}: the public API changed (api/{name}.txt):\n{}",
                    diff(&want, &got)
                );
            }
            Err(_) => {
                let _ = writeln!(failures, "\n{name}: no snapshot api/{name}.txt");
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{failures}\nIf the change is intended: UPDATE_API=1 cargo test -p xtask --test \
         public_api, and review the diff of api/ in the commit."
    );
}

/// The extractor sees what makes an API change: a field's type, `#[non_exhaustive]`, a new
/// variant, a signature, and nothing private or test-only.
#[test]
fn the_extractor_sees_signature_changes() {
    let dir = std::env::temp_dir().join(format!("public_api_{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(src.join("inner")).expect("temp dir");
    let write = |lib: &str| {
        std::fs::write(src.join("lib.rs"), lib).expect("lib.rs");
        snapshot(&dir, "demo")
    };
    std::fs::write(
        src.join("inner").join("mod.rs"),
        "pub fn deep(x: &[f64]) -> Option<usize> { None }\nfn hidden() {}\n",
    )
    .expect("inner/mod.rs");
    let base = "mod inner;\npub use inner::deep;\n\
                #[derive(Debug)]\npub struct S { pub a: Vec<String>, b: u8 }\n\
                pub enum E { A { k: usize }, B }\n\
                impl S { pub fn new() -> Self { S { a: Vec::new(), b: 0 } } fn private(&self) {} }\n\
                impl std::fmt::Display for S { fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result { Ok(()) } }\n\
                #[cfg(test)]\nmod tests { pub fn t() {} }\n";
    let a = write(base);
    for want in [
        "demo::inner: pub fn deep(x: &[f64]) -> Option<usize>",
        "demo: pub use inner::deep;",
        "demo: #[derive(Debug)] pub struct S { a: Vec<String>, /* 1 private */ }",
        "demo: pub enum E { A { k: usize }, B }",
        "demo: impl S { pub fn new() -> Self }",
        "demo: impl std::fmt::Display for S",
    ] {
        assert!(a.lines().any(|l| l == want), "{want:?} not in\n{a}");
    }
    assert!(
        !a.contains("hidden") && !a.contains("private(") && !a.contains("fn t()"),
        "{a}"
    );
    for changed in [
        base.replace("pub a: Vec<String>", "pub a: Vec<u8>"),
        base.replace(
            "#[derive(Debug)]\n",
            "#[derive(Debug)]\n#[non_exhaustive]\n",
        ),
        base.replace("B }", "B, C }"),
        base.replace("fn new() -> Self", "fn new(x: u8) -> Self"),
    ] {
        assert_ne!(write(&changed), a, "{changed}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The line of a public enum: its attributes, generics and variants.
fn enum_text(e: &syn::ItemEnum) -> String {
    let variants: Vec<String> = e
        .variants
        .iter()
        .map(|v| {
            format!(
                "{}{}{}",
                api_attrs(&v.attrs),
                v.ident,
                fields_text(&v.fields, false)
            )
        })
        .collect();
    format!(
        "{}pub enum {}{} {{ {} }}",
        api_attrs(&e.attrs),
        e.ident,
        tidy(&e.generics),
        variants.join(", ")
    )
}

/// The line of a public trait: its members (a default body as `{..}`) and supertraits.
fn trait_text(t: &syn::ItemTrait) -> String {
    let mut members = Vec::new();
    for ti in &t.items {
        match ti {
            syn::TraitItem::Fn(f) => members.push(format!(
                "{}{}",
                tidy(&f.sig),
                if f.default.is_some() { " {..}" } else { "" }
            )),
            syn::TraitItem::Type(ty) => {
                let mut ty = ty.clone();
                ty.attrs.clear();
                members.push(tidy(&ty));
            }
            syn::TraitItem::Const(c) => {
                let mut c = c.clone();
                c.attrs.clear();
                c.default = None;
                members.push(tidy(&c));
            }
            _ => {}
        }
    }
    let supertraits = if t.supertraits.is_empty() {
        String::new()
    } else {
        format!(": {}", tidy(&t.supertraits))
    };
    format!(
        "{}pub {}trait {}{}{} {{ {} }}",
        api_attrs(&t.attrs),
        if t.unsafety.is_some() { "unsafe " } else { "" },
        t.ident,
        tidy(&t.generics),
        supertraits,
        members.join("; ")
    )
}
