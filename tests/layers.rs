//! The layers of the workspace, checked against `cargo metadata`.
//!
//! Every workspace crate belongs to a layer by its folder, and may depend only on the layers
//! its layer lists (a crate may use its own layer only where that layer lists itself, or
//! where [`SIDEWAYS`] names the pair). Real drivers must not reach the simulator or its
//! renderer at all, not even through another crate ([`REAL_DRIVERS`]). The dependencies that
//! break these rules today are listed in [`EXCEPTIONS`], each with its reason: the check fails
//! on any violation not listed there, and on any listed one that no longer exists, so the list
//! only shrinks.
//!
//! Dependencies counted: normal and build dependencies (optional ones included: a feature can
//! switch them on), and dev-dependencies (a crate's tests are in its layer too; they are
//! checked by the same table and listed separately when they break it).
//!
//! **This file is the one place where the rules are written.** `docs/architecture.md` shows
//! them between the markers `<!-- begin: tests/layers.rs -->` and `<!-- end: tests/layers.rs
//! -->`; a test checks that copy, and `LAYERS_WRITE_DOC=1 cargo test --test layers` rewrites
//! it after a change here.

use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

// ------------------------------------------------------------------------------------------
// The rules.
// ------------------------------------------------------------------------------------------

/// A layer: the folders of its crates (`dir/*` = every folder directly under `dir`; an exact
/// folder wins over a `*` one) and the layers its crates may depend on.
struct Layer {
    name: &'static str,
    folders: &'static [&'static str],
    may_use: &'static [&'static str],
}

/// The layers, bottom first.
const LAYERS: &[Layer] = &[
    Layer {
        name: "protocol",
        folders: &["protocol"],
        may_use: &[],
    },
    Layer {
        name: "runtime",
        folders: &["runtime"],
        may_use: &["protocol"],
    },
    Layer {
        name: "libs",
        folders: &["libs/*", "tools"],
        may_use: &["protocol", "runtime", "libs"],
    },
    Layer {
        name: "driver api",
        folders: &["drivers/api"],
        may_use: &["protocol", "runtime", "libs"],
    },
    Layer {
        name: "drivers",
        folders: &["drivers/*"],
        may_use: &["protocol", "runtime", "libs", "driver api"],
    },
    Layer {
        name: "actors",
        folders: &["actors/*", "robot"],
        may_use: &["protocol", "runtime", "libs", "driver api", "drivers"],
    },
    Layer {
        name: "edges",
        folders: &["edges/*"],
        may_use: &["protocol", "runtime", "libs"],
    },
    Layer {
        name: "fakes",
        folders: &["fakes/*"],
        may_use: &["protocol", "runtime", "libs", "driver api", "drivers"],
    },
    Layer {
        name: "binary",
        folders: &[".", "config", "bench"],
        may_use: &[
            "protocol",
            "runtime",
            "libs",
            "driver api",
            "drivers",
            "actors",
            "edges",
            "fakes",
            "binary",
        ],
    },
];

/// Dependencies inside a layer that does not list itself, allowed for good: (from, to, why).
const SIDEWAYS: &[(&str, &str, &str)] = &[
    (
        "robotd-driver-widowx",
        "robotd-driver-mjpeg",
        "the WidowX's wrist camera is an MJPEG stream",
    ),
    (
        "robotd-driver-widowx",
        "robotd-driver-v4l2",
        "or a V4L2 device",
    ),
    (
        "robotd-robot",
        "robotd-arm",
        "robot starts the hardware actors on the chosen driver",
    ),
    (
        "robotd-robot",
        "robotd-gripper",
        "robot starts the hardware actors on the chosen driver",
    ),
    (
        "robotd-robot",
        "robotd-camera",
        "robot starts the hardware actors on the chosen driver",
    ),
];

/// Drivers of real hardware: none of them may depend on a crate of [`SIMULATOR`], directly or
/// through other crates (normal dependencies).
const REAL_DRIVERS: &[&str] = &[
    "robotd-driver-niryo",
    "robotd-driver-widowx",
    "robotd-driver-mjpeg",
    "robotd-driver-v4l2",
];

/// The simulator and its renderer.
const SIMULATOR: &[&str] = &["robotd-driver-sim", "robotd-sim", "robotd-render"];

/// Normal (and build) dependencies, or dev-dependencies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Kind {
    Normal,
    Dev,
}

/// Dependencies that break the rules, allowed until they are removed: (from, to, kind, why).
/// Empty since issue 40 removed the last two. Nothing may be added here without a reason; an
/// entry that is no longer a violation fails the check.
const EXCEPTIONS: &[(&str, &str, Kind, &str)] = &[];

// ------------------------------------------------------------------------------------------
// The check.
// ------------------------------------------------------------------------------------------

/// A workspace crate as the check sees it.
#[derive(Debug, Clone)]
struct Crate {
    name: String,
    /// Its folder relative to the workspace root (`.` for the root package).
    folder: String,
    /// Workspace crates it depends on, with the kind.
    deps: BTreeSet<(String, Kind)>,
}

/// The layer of a folder: an exact folder first, then a `dir/*` one.
fn layer_of(folder: &str) -> Option<&'static Layer> {
    let exact = LAYERS.iter().find(|l| l.folders.contains(&folder));
    exact.or_else(|| {
        LAYERS.iter().find(|l| {
            l.folders.iter().any(|pattern| {
                pattern.strip_suffix("/*").is_some_and(|dir| {
                    folder
                        .strip_prefix(dir)
                        .and_then(|rest| rest.strip_prefix('/'))
                        .is_some_and(|rest| !rest.is_empty() && !rest.contains('/'))
                })
            })
        })
    })
}

fn kind_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Normal => "dependency",
        Kind::Dev => "dev-dependency",
    }
}

/// What is wrong with `crates` under the rules above and `exceptions`: one line each.
fn check(crates: &[Crate], exceptions: &[(&str, &str, Kind, &str)]) -> Vec<String> {
    let mut problems = Vec::new();
    let by_name: BTreeMap<&str, &Crate> = crates.iter().map(|c| (c.name.as_str(), c)).collect();
    let mut violations = BTreeSet::new();
    for krate in crates {
        let Some(layer) = layer_of(&krate.folder) else {
            problems.push(format!(
                "{} ({}) is in no layer: add its folder to LAYERS in tests/layers.rs",
                krate.name, krate.folder
            ));
            continue;
        };
        for (dep, kind) in &krate.deps {
            let Some(target) = by_name.get(dep.as_str()) else {
                continue;
            };
            let Some(target_layer) = layer_of(&target.folder) else {
                continue; // reported as a crate in no layer
            };
            let allowed = layer.may_use.contains(&target_layer.name)
                || SIDEWAYS
                    .iter()
                    .any(|(from, to, _)| *from == krate.name && to == dep);
            if allowed {
                continue;
            }
            violations.insert((krate.name.clone(), dep.clone(), *kind));
            let listed = exceptions
                .iter()
                .any(|(from, to, k, _)| *from == krate.name && to == dep && k == kind);
            if !listed {
                problems.push(format!(
                    "{} ({}, layer {}) → {} ({}, layer {}), a {}: the {} layer may use {}",
                    krate.name,
                    krate.folder,
                    layer.name,
                    dep,
                    target.folder,
                    target_layer.name,
                    kind_name(*kind),
                    layer.name,
                    if layer.may_use.is_empty() {
                        "nothing".to_owned()
                    } else {
                        layer.may_use.join(", ")
                    }
                ));
            }
        }
    }
    for (from, to, kind, _) in exceptions {
        if !violations.contains(&(from.to_string(), to.to_string(), *kind)) {
            problems.push(format!(
                "the exception {from} → {to} ({}) is no longer a violation: remove it from \
                 EXCEPTIONS in tests/layers.rs (then LAYERS_WRITE_DOC=1 cargo test --test layers)",
                kind_name(*kind)
            ));
        }
    }
    for driver in REAL_DRIVERS {
        if !by_name.contains_key(driver) {
            problems.push(format!("{driver} of REAL_DRIVERS is not a workspace crate"));
            continue;
        }
        // Breadth-first over normal dependencies, keeping the path for the message.
        let mut paths: BTreeMap<&str, Vec<&str>> = BTreeMap::from([(*driver, vec![*driver])]);
        let mut queue = vec![*driver];
        while let Some(name) = queue.pop() {
            let path = paths[name].clone();
            for (dep, kind) in &by_name[name].deps {
                if *kind != Kind::Normal || paths.contains_key(dep.as_str()) {
                    continue;
                }
                let Some(target) = by_name.get(dep.as_str()) else {
                    continue;
                };
                let mut next = path.clone();
                next.push(target.name.as_str());
                paths.insert(target.name.as_str(), next);
                queue.push(target.name.as_str());
            }
        }
        for simulated in SIMULATOR {
            if let Some(path) = paths.get(simulated) {
                problems.push(format!(
                    "the real driver {driver} depends on the simulator: {}",
                    path.join(" → ")
                ));
            }
        }
    }
    problems
}

// ------------------------------------------------------------------------------------------
// The workspace and its documentation.
// ------------------------------------------------------------------------------------------

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace's crates, read with `cargo metadata --no-deps`.
fn workspace() -> Vec<Crate> {
    let output = std::process::Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(root())
        .output()
        .expect("running cargo metadata");
    assert!(
        output.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let metadata: Value = serde_json::from_slice(&output.stdout).expect("cargo metadata's JSON");
    let workspace_root = PathBuf::from(
        metadata["workspace_root"]
            .as_str()
            .expect("metadata's workspace_root"),
    );
    let packages = metadata["packages"]
        .as_array()
        .expect("metadata's packages");
    let names: BTreeSet<&str> = packages.iter().filter_map(|p| p["name"].as_str()).collect();
    packages
        .iter()
        .map(|p| {
            let manifest = Path::new(p["manifest_path"].as_str().expect("a manifest path"));
            let folder = manifest
                .parent()
                .and_then(|dir| dir.strip_prefix(&workspace_root).ok())
                .map(|dir| dir.to_string_lossy().into_owned())
                .filter(|dir| !dir.is_empty())
                .unwrap_or_else(|| ".".to_owned());
            let deps = p["dependencies"]
                .as_array()
                .expect("a package's dependencies")
                .iter()
                .filter_map(|d| {
                    let name = d["name"].as_str()?;
                    let kind = match d["kind"].as_str() {
                        Some("dev") => Kind::Dev,
                        _ => Kind::Normal,
                    };
                    names.contains(name).then(|| (name.to_owned(), kind))
                })
                .collect();
            Crate {
                name: p["name"].as_str().expect("a package name").to_owned(),
                folder,
                deps,
            }
        })
        .collect()
}

const BEGIN: &str = "<!-- begin: tests/layers.rs -->\n";
const END: &str = "<!-- end: tests/layers.rs -->";

/// The rules as `docs/architecture.md` shows them.
fn rules_as_markdown() -> String {
    let mut md = String::from("| layer | folders | may use |\n|---|---|---|\n");
    for layer in LAYERS {
        let folders: Vec<String> = layer.folders.iter().map(|f| format!("`{f}`")).collect();
        let may_use = if layer.may_use.is_empty() {
            "—".to_owned()
        } else {
            layer.may_use.join(", ")
        };
        md.push_str(&format!(
            "| {} | {} | {} |\n",
            layer.name,
            folders.join(", "),
            may_use
        ));
    }
    md.push_str("\nAllowed inside a layer that does not list itself:\n\n");
    for (from, to, why) in SIDEWAYS {
        md.push_str(&format!("- `{from}` → `{to}`: {why}\n"));
    }
    let quoted = |names: &[&str]| {
        names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    md.push_str(&format!(
        "\nThe real drivers ({}) depend on none of {}, not even through another crate.\n",
        quoted(REAL_DRIVERS),
        quoted(SIMULATOR)
    ));
    let mut exceptions = EXCEPTIONS.iter().peekable();
    if exceptions.peek().is_none() {
        md.push_str("\nKnown exceptions: none. Every dependency follows these rules.\n");
        return md;
    }
    md.push_str("\nKnown exceptions (today's violations, to be removed):\n\n");
    for (from, to, kind, why) in exceptions {
        let dev = if *kind == Kind::Dev {
            " (dev-dependency)"
        } else {
            ""
        };
        md.push_str(&format!("- `{from}` → `{to}`{dev}: {why}\n"));
    }
    md
}

// ------------------------------------------------------------------------------------------
// The tests.
// ------------------------------------------------------------------------------------------

#[test]
fn every_dependency_follows_the_layers_or_is_a_listed_exception() {
    let crates = workspace();
    assert!(
        crates.len() > 30,
        "only {} crates in cargo metadata: is the reading broken?",
        crates.len()
    );
    let problems = check(&crates, EXCEPTIONS);
    assert!(
        problems.is_empty(),
        "{} layer problem(s) (rules in tests/layers.rs, explained in docs/architecture.md):\n  {}",
        problems.len(),
        problems.join("\n  ")
    );
}

#[test]
fn the_architecture_page_shows_these_rules() {
    let path = root().join("docs/architecture.md");
    let text = std::fs::read_to_string(&path).expect("reading docs/architecture.md");
    let (Some(begin), Some(end)) = (text.find(BEGIN), text.find(END)) else {
        panic!(
            "docs/architecture.md has no `{}` … `{END}` block",
            BEGIN.trim()
        );
    };
    let shown = &text[begin + BEGIN.len()..end];
    let expected = rules_as_markdown();
    if shown == expected {
        return;
    }
    if std::env::var_os("LAYERS_WRITE_DOC").is_some() {
        let updated = format!(
            "{}{}{}",
            &text[..begin + BEGIN.len()],
            expected,
            &text[end..]
        );
        std::fs::write(&path, updated).expect("writing docs/architecture.md");
        return;
    }
    panic!(
        "docs/architecture.md shows other layer rules than tests/layers.rs; run \
         LAYERS_WRITE_DOC=1 cargo test --test layers, or put this between the markers:\n{expected}"
    );
}

/// The check itself on a small made-up workspace: each kind of problem is caught.
#[test]
fn the_check_catches_each_kind_of_problem() {
    let krate = |name: &str, folder: &str, deps: &[(&str, Kind)]| Crate {
        name: name.to_owned(),
        folder: folder.to_owned(),
        deps: deps.iter().map(|(d, k)| (d.to_string(), *k)).collect(),
    };
    let crates = vec![
        krate("robotd-protocol", "protocol", &[]),
        krate(
            "robotd-render",
            "libs/render",
            &[("robotd-protocol", Kind::Normal)],
        ),
        krate(
            "robotd-jpeg",
            "libs/jpeg",
            &[("robotd-render", Kind::Normal)],
        ),
        krate(
            "robotd-driver",
            "drivers/api",
            &[("robotd-protocol", Kind::Normal)],
        ),
        krate(
            "robotd-driver-niryo",
            "drivers/niryo",
            // Through a lib to the renderer: a real driver reaching the simulator.
            &[
                ("robotd-driver", Kind::Normal),
                ("robotd-jpeg", Kind::Normal),
            ],
        ),
        krate("robotd-driver-widowx", "drivers/widowx", &[]),
        krate("robotd-driver-mjpeg", "drivers/mjpeg", &[]),
        krate("robotd-driver-v4l2", "drivers/v4l2", &[]),
        krate(
            "robotd-driver-sim",
            "drivers/sim",
            &[("robotd-fake-niryo", Kind::Dev)], // drivers → fakes: up
        ),
        krate(
            "robotd-fake-niryo",
            "fakes/niryo",
            &[("robotd-driver-sim", Kind::Normal)],
        ),
        krate(
            "robotd-arm",
            "actors/arm",
            &[("robotd-driver", Kind::Normal)],
        ),
        krate("robotd-http", "edges/http", &[("robotd-arm", Kind::Normal)]), // edge → actor
        krate("robotd-mcp", "edges/mcp", &[("robotd-http", Kind::Normal)]),  // edge → edge
        krate("robotd-odd", "somewhere/else", &[]),
    ];
    let exceptions = [
        ("robotd-mcp", "robotd-http", Kind::Normal, "listed"),
        (
            "robotd-arm",
            "robotd-driver",
            Kind::Normal,
            "not a violation",
        ),
    ];
    let problems = check(&crates, &exceptions);
    let expect = [
        "robotd-driver-sim (drivers/sim, layer drivers) → robotd-fake-niryo (fakes/niryo, layer fakes), a dev-dependency",
        "robotd-http (edges/http, layer edges) → robotd-arm (actors/arm, layer actors), a dependency",
        "the exception robotd-arm → robotd-driver (dependency) is no longer a violation",
        "the real driver robotd-driver-niryo depends on the simulator: robotd-driver-niryo → robotd-jpeg → robotd-render",
        "robotd-odd (somewhere/else) is in no layer",
    ];
    for wanted in expect {
        assert!(
            problems.iter().any(|p| p.contains(wanted)),
            "no problem says {wanted:?}; problems:\n  {}",
            problems.join("\n  ")
        );
    }
    assert_eq!(problems.len(), expect.len(), "{problems:#?}");
}
