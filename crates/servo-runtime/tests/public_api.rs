//! The crate's whole public surface, listed: every public path (items at the root, in public
//! modules, and what they re-export; `#[doc(hidden)]` ones included) and every public method
//! of the types it names (its own and those it re-exports from servo-config), with every
//! feature on. `public-api.txt` beside the manifest is
//! the listing checked in: the test fails when it is stale (`FTS_WRITE_API=1` rewrites it), so
//! a change of the surface an embedder relies on shows in review. It also holds the surface to
//! its size: at most 25 items at the root, 40 in all (methods aside).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use syn::{ImplItem, Item, UseTree, Visibility};

/// Items at the root at most (the front door: the loop, its deployment, samples, errors).
const MAX_ROOT_ITEMS: usize = 25;
/// Items in all at most, public modules' included (methods aside).
const MAX_ITEMS: usize = 40;

/// What the crate exposes.
#[derive(Default)]
struct Surface {
    /// `path kind` of every public item.
    items: BTreeSet<String>,
    /// `Type::method` of every public inherent method of a type an embedder can name.
    methods: BTreeSet<String>,
    /// `Type::method` of every public inherent method found here or in servo-config (an
    /// inherent impl is in its type's crate), whether its type is public.
    all_methods: BTreeSet<String>,
}

fn is_pub(v: &Visibility) -> bool {
    matches!(v, Visibility::Public(_))
}

fn parse(path: &Path) -> syn::File {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The file of module `name` declared in `dir` (`name.rs` or `name/mod.rs`).
fn module_file(dir: &Path, name: &str) -> (PathBuf, PathBuf) {
    let flat = dir.join(format!("{name}.rs"));
    if flat.exists() {
        (flat, dir.join(name))
    } else {
        (dir.join(name).join("mod.rs"), dir.join(name))
    }
}

/// The names a `pub use` tree brings in (a glob is refused: it would hide what it exports).
fn use_names(tree: &UseTree, out: &mut Vec<String>) {
    match tree {
        UseTree::Path(p) => use_names(&p.tree, out),
        UseTree::Name(n) => out.push(n.ident.to_string()),
        UseTree::Rename(r) => out.push(r.rename.to_string()),
        UseTree::Group(g) => g.items.iter().for_each(|t| use_names(t, out)),
        UseTree::Glob(_) => panic!("a glob re-export hides what it exports: name each item"),
    }
}

fn type_name(ty: &syn::Type) -> Option<String> {
    match ty {
        syn::Type::Path(p) => p.path.segments.last().map(|s| s.ident.to_string()),
        _ => None,
    }
}

/// Walks the items of one module: `prefix` is its public path (None: the module is private,
/// only its methods and re-exports through public paths count).
fn walk(items: &[Item], prefix: Option<&str>, dir: &Path, s: &mut Surface) {
    let at = |name: &str| match prefix {
        Some("") => Some(name.to_owned()),
        Some(p) => Some(format!("{p}::{name}")),
        None => None,
    };
    for item in items {
        let named = |vis: &Visibility, ident: &syn::Ident, kind: &str, s: &mut Surface| {
            if let Some(path) = at(&ident.to_string()).filter(|_| is_pub(vis)) {
                s.items.insert(format!("{path} {kind}"));
            }
        };
        match item {
            Item::Struct(i) => named(&i.vis, &i.ident, "struct", s),
            Item::Enum(i) => named(&i.vis, &i.ident, "enum", s),
            Item::Trait(i) => named(&i.vis, &i.ident, "trait", s),
            Item::Fn(i) => named(&i.vis, &i.sig.ident, "fn", s),
            Item::Const(i) => named(&i.vis, &i.ident, "const", s),
            Item::Static(i) => named(&i.vis, &i.ident, "static", s),
            Item::Type(i) => named(&i.vis, &i.ident, "type", s),
            Item::Union(i) => named(&i.vis, &i.ident, "union", s),
            Item::Macro(i) if i.mac.path.is_ident("macro_rules") => {
                if let Some(ident) = &i.ident {
                    s.items.insert(format!("{ident} macro"));
                }
            }
            Item::Use(u) if is_pub(&u.vis) => {
                let mut names = Vec::new();
                use_names(&u.tree, &mut names);
                for n in names {
                    if let Some(path) = at(&n) {
                        s.items.insert(format!("{path} use"));
                    }
                }
            }
            Item::Impl(i) if i.trait_.is_none() => {
                let Some(ty) = type_name(&i.self_ty) else {
                    continue;
                };
                for m in &i.items {
                    match m {
                        ImplItem::Fn(f) if is_pub(&f.vis) => {
                            s.all_methods.insert(format!("{ty}::{}", f.sig.ident));
                        }
                        ImplItem::Const(c) if is_pub(&c.vis) => {
                            s.all_methods.insert(format!("{ty}::{}", c.ident));
                        }
                        _ => {}
                    }
                }
            }
            Item::Mod(m) => {
                let public = is_pub(&m.vis);
                let name = m.ident.to_string();
                let inner = if public { at(&name) } else { None };
                if public {
                    if let Some(path) = &inner {
                        s.items.insert(format!("{path} mod"));
                    }
                }
                match &m.content {
                    Some((_, items)) => walk(items, inner.as_deref(), &dir.join(&name), s),
                    None => {
                        let (file, sub) = module_file(dir, &name);
                        walk(&parse(&file).items, inner.as_deref(), &sub, s);
                    }
                }
            }
            _ => {}
        }
    }
}

fn surface() -> Surface {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut s = Surface::default();
    walk(&parse(&src.join("lib.rs")).items, Some(""), &src, &mut s);
    // The types re-exported from servo-config bring their methods: walked for those only.
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../servo-config/src");
    let mut theirs = Surface::default();
    walk(
        &parse(&config.join("lib.rs")).items,
        None,
        &config,
        &mut theirs,
    );
    s.all_methods.extend(theirs.all_methods);
    // Methods of the types an embedder can name (public at some path of this crate).
    let named: BTreeSet<String> = s
        .items
        .iter()
        .filter_map(|i| i.split(' ').next())
        .map(|p| p.rsplit("::").next().unwrap_or(p).to_owned())
        .collect();
    s.methods = s
        .all_methods
        .iter()
        .filter(|m| named.contains(m.split("::").next().unwrap_or("")))
        .cloned()
        .collect();
    s
}

fn listing(s: &Surface) -> String {
    let mut out = String::from(
        "# servo-runtime's public surface with every feature on (tests/public_api.rs; \
         FTS_WRITE_API=1 rewrites it)\n\n## items (path kind)\n",
    );
    s.items.iter().for_each(|i| out.push_str(&format!("{i}\n")));
    out.push_str("\n## methods of the types it names\n");
    s.methods
        .iter()
        .for_each(|m| out.push_str(&format!("{m}\n")));
    out
}

#[test]
fn the_public_surface_is_the_listed_one_and_small() {
    let s = surface();
    let root = s.items.iter().filter(|i| !i.contains("::")).count();
    assert!(
        root <= MAX_ROOT_ITEMS,
        "{root} items at the root (at most {MAX_ROOT_ITEMS}):\n{}",
        listing(&s)
    );
    assert!(
        s.items.len() <= MAX_ITEMS,
        "{} items in all (at most {MAX_ITEMS}):\n{}",
        s.items.len(),
        listing(&s)
    );
    // The front door is there (a listing that lost the walk would be small too).
    for front in [
        "Servo use",
        "Deployment use",
        "deployment mod",
        "ConfigError use",
    ] {
        assert!(s.items.contains(front), "{front} missing:\n{}", listing(&s));
    }
    for method in [
        "Servo::tick",
        "Servo::from_file",
        "Servo::serve",
        "Servo::swap",
    ] {
        assert!(
            s.methods.contains(method),
            "{method} missing:\n{}",
            listing(&s)
        );
    }
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("public-api.txt");
    let now = listing(&s);
    if std::env::var_os("FTS_WRITE_API").is_some() {
        std::fs::write(&file, &now).expect("write public-api.txt");
        return;
    }
    let checked_in = std::fs::read_to_string(&file).unwrap_or_default();
    assert!(
        checked_in == now,
        "{} is stale: the public surface changed (review the change, then rerun with \
         FTS_WRITE_API=1 to rewrite it). Now:\n{now}",
        file.display()
    );
}
