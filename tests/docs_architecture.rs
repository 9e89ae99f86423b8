//! The documentation points at files that exist.
//!
//! - Every repository path that `docs/architecture.md` names in backticks exists. A span is
//!   taken as a path when it is relative (no leading `/`, no `://`), has no space, `{` or `*`
//!   (placeholders and globs are written that way on purpose), and contains a `/` or ends in
//!   `.rs`, `.toml`, `.md` or `.py`. Names of the bus catalogue (`arm/command`, …) look like
//!   paths but are topics and services, so they are skipped; so are fenced code blocks (the
//!   pictures).
//! - Every relative Markdown link (`[text](target)`) in `README.md`, `BENCHMARKS.md` and
//!   `docs/*.md` points at an existing file or folder. Web links and links to an anchor of the
//!   same page are not checked; a link to an anchor of another Markdown file also checks that
//!   the file has a heading with that anchor.
//!
//! The paths are relative to the repository root (`CARGO_MANIFEST_DIR`).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

/// The text outside fenced code blocks (lines between ``` or ~~~ fences are dropped).
fn outside_fences(text: &str) -> String {
    let mut out = String::new();
    let mut fence: Option<&str> = None;
    for line in text.lines() {
        let trimmed = line.trim_start();
        match fence {
            Some(marker) => {
                if trimmed.starts_with(marker) {
                    fence = None;
                }
            }
            None => {
                if trimmed.starts_with("```") {
                    fence = Some("```");
                } else if trimmed.starts_with("~~~") {
                    fence = Some("~~~");
                } else {
                    out.push_str(line);
                    out.push('\n');
                }
            }
        }
    }
    out
}

/// The contents of the inline code spans of `text`: a run of N backticks opens a span, the next
/// run of exactly N closes it (CommonMark's rule); an unclosed run is literal text.
fn code_spans(text: &str) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    let run_at = |i: usize| chars[i..].iter().take_while(|&&c| c == '`').count();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        if chars[i] != '`' {
            i += 1;
            continue;
        }
        let open = run_at(i);
        let start = i + open;
        let mut j = start;
        let mut close = None;
        while j < chars.len() {
            if chars[j] == '`' {
                let run = run_at(j);
                if run == open {
                    close = Some(j);
                    break;
                }
                j += run;
            } else {
                j += 1;
            }
        }
        match close {
            Some(end) => {
                let span: String = chars[start..end].iter().collect();
                spans.push(span.trim().to_owned());
                i = end + open;
            }
            None => i = start,
        }
    }
    spans
}

/// Whether a code span names a repository path (see the module's doc).
fn looks_like_repository_path(span: &str) -> bool {
    if span.is_empty()
        || span.starts_with('/')
        || span.contains("://")
        || span.contains(char::is_whitespace)
        || span.contains('{')
        || span.contains('*')
    {
        return false;
    }
    span.contains('/')
        || [".rs", ".toml", ".md", ".py"]
            .iter()
            .any(|ext| span.ends_with(ext))
}

/// The names of every topic, frame topic and service of the bus catalogue.
fn catalogue_names() -> HashSet<String> {
    robotd_topics::entries()
        .iter()
        .map(|entry| entry.name().to_owned())
        .collect()
}

fn repository_paths_in(text: &str, skip: &HashSet<String>) -> Vec<String> {
    let mut seen = HashSet::new();
    code_spans(&outside_fences(text))
        .into_iter()
        .filter(|span| looks_like_repository_path(span) && !skip.contains(span))
        .filter(|span| seen.insert(span.clone()))
        .collect()
}

#[test]
fn every_path_the_architecture_page_names_exists() {
    let root = root();
    let text = read(&root.join("docs/architecture.md"));
    let catalogue = catalogue_names();
    let paths = repository_paths_in(&text, &catalogue);
    assert!(
        paths.len() > 50,
        "only {} paths found in docs/architecture.md: is the extraction broken?",
        paths.len()
    );
    let missing: Vec<&String> = paths.iter().filter(|p| !root.join(p).exists()).collect();
    assert!(
        missing.is_empty(),
        "docs/architecture.md names {} path(s) that do not exist in the repository:\n  {}",
        missing.len(),
        missing
            .iter()
            .map(|p| p.as_str())
            .collect::<Vec<_>>()
            .join("\n  ")
    );
}

/// The targets of the inline links and images of `text`, outside code.
fn link_targets(text: &str) -> Vec<String> {
    let text = outside_fences(text);
    // Drop inline code first, so that `[a](b)` inside backticks is not taken for a link.
    let mut plain = String::new();
    let mut in_code = false;
    for c in text.chars() {
        if c == '`' {
            in_code = !in_code;
        } else if !in_code {
            plain.push(c);
        }
    }
    let mut targets = Vec::new();
    let mut rest = plain.as_str();
    while let Some(at) = rest.find("](") {
        let after = &rest[at + 2..];
        // The target ends at the matching ')' (targets may hold balanced parentheses).
        let mut depth = 0usize;
        let mut end = None;
        for (i, c) in after.char_indices() {
            match c {
                '(' => depth += 1,
                ')' if depth == 0 => {
                    end = Some(i);
                    break;
                }
                ')' => depth -= 1,
                '\n' => break,
                _ => {}
            }
        }
        if let Some(end) = end {
            // An optional title after the target: `(path "title")`.
            let target = after[..end].split_whitespace().next().unwrap_or("");
            let target = target.trim_start_matches('<').trim_end_matches('>');
            targets.push(target.to_owned());
            rest = &after[end..];
        } else {
            rest = after;
        }
    }
    targets
}

/// GitHub's anchor for a heading: lower case, letters, digits, `-` and `_` kept, spaces
/// turned into `-`, everything else dropped.
fn anchor_of(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown file's headings (repeated headings get `-1`, `-2`, … as on GitHub).
fn anchors(text: &str) -> HashSet<String> {
    let mut found = HashSet::new();
    for line in outside_fences(text).lines() {
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if hashes == 0 || hashes > 6 || !line[hashes..].starts_with(' ') {
            continue;
        }
        let heading: String = line[hashes..].chars().filter(|&c| c != '`').collect();
        let base = anchor_of(&heading);
        let mut anchor = base.clone();
        let mut n = 0;
        while !found.insert(anchor.clone()) {
            n += 1;
            anchor = format!("{base}-{n}");
        }
    }
    found
}

fn markdown_files(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("README.md"), root.join("BENCHMARKS.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("reading docs/")
        .map(|entry| entry.expect("a docs/ entry").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

#[test]
fn every_relative_link_of_the_readme_and_docs_points_at_a_file() {
    let root = root();
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in markdown_files(&root) {
        let text = read(&file);
        let shown = file
            .strip_prefix(&root)
            .unwrap_or(&file)
            .display()
            .to_string();
        for target in link_targets(&text) {
            if target.is_empty()
                || target.starts_with('#')
                || target.contains("://")
                || target.starts_with("mailto:")
            {
                continue;
            }
            checked += 1;
            let (path, anchor) = match target.split_once('#') {
                Some((path, anchor)) => (path, Some(anchor)),
                None => (target.as_str(), None),
            };
            let resolved = file.parent().expect("a file's folder").join(path);
            if !resolved.exists() {
                broken.push(format!("{shown}: ({target}): no such file"));
                continue;
            }
            if let Some(anchor) = anchor {
                if resolved.extension().is_some_and(|ext| ext == "md")
                    && !anchors(&read(&resolved)).contains(anchor)
                {
                    broken.push(format!("{shown}: ({target}): no heading with that anchor"));
                }
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} links checked: is the extraction broken?"
    );
    assert!(
        broken.is_empty(),
        "{} broken link(s):\n  {}",
        broken.len(),
        broken.join("\n  ")
    );
}

#[test]
fn the_extraction_finds_paths_and_links_and_skips_the_rest() {
    let skip: HashSet<String> = ["arm/command".to_owned()].into_iter().collect();
    let text = "See `src/serve.rs`, `Cargo.toml`, `actors/arm/`, `arm/command`, `/health`,\n\
                `http://x/y`, `tools/src/tools/{name}.rs`, `drivers/*`, `robotd bench mcp`,\n\
                ``a `tick` inside``, `lib.rs` and `plain`.\n\
                ```\n`inside/a/fence.rs`\n```\n";
    assert_eq!(
        repository_paths_in(text, &skip),
        ["src/serve.rs", "Cargo.toml", "actors/arm/", "lib.rs"]
    );
    let links = "[a](docs/x.md) ![b](images/y.png \"title\") [c](#here) [d](https://e.org/f)\n\
                 `[not](a-link.md)` [e](other.md#some-heading)";
    assert_eq!(
        link_targets(links),
        [
            "docs/x.md",
            "images/y.png",
            "#here",
            "https://e.org/f",
            "other.md#some-heading"
        ]
    );
    assert_eq!(anchor_of("The HTTP port's guard"), "the-http-ports-guard");
    assert_eq!(
        anchor_of("Perception robustness (randomized frames)"),
        "perception-robustness-randomized-frames"
    );
    assert_eq!(anchor_of("`robot_camera`"), "robot_camera");
}
