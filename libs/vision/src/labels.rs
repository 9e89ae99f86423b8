//! The label table: which colours the built-in detector tells apart, and how a measured object
//! (colour, shape class, longest side) is named.
//!
//! The table lives in a TOML file (`config/labels.toml` is built in; a lab can give its own),
//! so naming objects is configuration, not code. A rule also says how tall its objects are,
//! because a camera looking down sees the *top* face of an object, displaced by parallax: the
//! detector needs the height to put the object where it really stands.
//!
//! ```
//! use robotd_vision::labels::{LabelTable, ShapeClass};
//!
//! let table = LabelTable::builtin();
//! let rule = table.rule_for("yellow", ShapeClass::Bar, 0.12).unwrap();
//! assert_eq!(rule.label, "pencil");
//! assert_eq!(rule.height_for(0.012, 0.12), 0.010);
//! let cube = table.rule_for("red", ShapeClass::Square, 0.03).unwrap();
//! assert_eq!(cube.height_for(0.03, 0.031), 0.03); // "side": as tall as its shorter side
//! assert!(table.rule_for("red", ShapeClass::Square, 0.5).is_none()); // too big for the rule
//! ```

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// The built-in label table (`config/labels.toml`).
pub const BUILTIN_LABELS_TOML: &str = include_str!("../../../config/labels.toml");

/// The shape of an object's top face, as the detector measures it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeClass {
    /// A rectangle about as long as wide (long/short < 1.3).
    Square,
    /// A rectangle up to 2.5 times as long as wide.
    Rectangle,
    /// A long thin rectangle (more than 2.5 times as long as wide).
    Bar,
    /// In a rule: any of square, rectangle or bar.
    Box,
    /// A disc (the top of a cylinder).
    Round,
    /// In a rule: any shape.
    Any,
}

impl ShapeClass {
    /// Whether a rule's shape accepts a measured shape.
    pub fn accepts(self, measured: ShapeClass) -> bool {
        match self {
            ShapeClass::Any => true,
            ShapeClass::Box => matches!(
                measured,
                ShapeClass::Square | ShapeClass::Rectangle | ShapeClass::Bar
            ),
            other => other == measured,
        }
    }

    /// The class of a measured top face: `aspect` = long side / short side of its
    /// minimum-area rectangle, `fill` = its area / the rectangle's area.
    pub fn measure(aspect: f64, fill: f64) -> ShapeClass {
        if fill < 0.88 && aspect < 1.25 {
            ShapeClass::Round
        } else if aspect < 1.3 {
            ShapeClass::Square
        } else if aspect <= 2.5 {
            ShapeClass::Rectangle
        } else {
            ShapeClass::Bar
        }
    }

    /// The word used in fallback labels (`"red box"`).
    pub fn noun(self) -> &'static str {
        match self {
            ShapeClass::Round => "cylinder",
            ShapeClass::Bar => "bar",
            _ => "box",
        }
    }
}

/// How tall the objects of a rule are.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeightRule {
    /// A fixed height, metres.
    Fixed(f64),
    /// As tall as the shorter side of the top face (cubes).
    Side,
}

/// One naming rule of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelRule {
    /// The label (lower-case).
    pub label: String,
    /// Index of its colour in [`LabelTable::colours`].
    pub colour: usize,
    /// Shapes it accepts.
    pub shape: ShapeClass,
    /// Smallest longest side, metres.
    pub min_size_m: f64,
    /// Largest longest side, metres.
    pub max_size_m: f64,
    /// Height of its objects.
    pub height: HeightRule,
}

impl LabelRule {
    /// Height of an object of this rule whose top face measures `short_m` × `long_m`.
    pub fn height_for(&self, short_m: f64, long_m: f64) -> f64 {
        let _ = long_m;
        match self.height {
            HeightRule::Fixed(h) => h,
            HeightRule::Side => short_m,
        }
    }
}

/// A colour the detector tells apart.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourRef {
    /// Its name (lower-case), the first word of fallback labels.
    pub name: String,
    /// Its value lit from above.
    pub rgb: [u8; 3],
    /// Its hue signature: `(rgb − min) / (max − min)`, unchanged by shading and by blending
    /// with white or black.
    pub signature: [f32; 3],
}

/// The hue signature of a colour: `(rgb − min) / (max − min)`; `None` for greys (no hue).
pub fn hue_signature(rgb: [f32; 3]) -> Option<[f32; 3]> {
    let max = rgb[0].max(rgb[1]).max(rgb[2]);
    let min = rgb[0].min(rgb[1]).min(rgb[2]);
    let chroma = max - min;
    (chroma > 1.0).then(|| rgb.map(|c| (c - min) / chroma))
}

/// The colours and naming rules of the built-in detector.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelTable {
    /// Colours the detector tells apart (at most 254).
    pub colours: Vec<ColourRef>,
    /// Naming rules, tried in order.
    pub rules: Vec<LabelRule>,
}

/// A label table file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum LabelTableError {
    /// The file could not be read.
    #[error("cannot read the label table {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The file is not valid TOML of the expected shape.
    #[error("label table {origin}: {reason}")]
    Parse {
        /// File name or "built-in".
        origin: String,
        /// What is wrong.
        reason: String,
    },
    /// A value is out of range or inconsistent.
    #[error("label table {origin}: {problems}")]
    Invalid {
        /// File name or "built-in".
        origin: String,
        /// Every problem, `; `-separated.
        problems: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TableFile {
    colours: BTreeMap<String, [u8; 3]>,
    #[serde(default)]
    labels: Vec<RuleFile>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RuleFile {
    label: String,
    color: String,
    shape: ShapeClass,
    size_m: [f64; 2],
    height_m: HeightFile,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum HeightFile {
    Metres(f64),
    Word(String),
}

impl fmt::Display for HeightRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HeightRule::Fixed(h) => write!(f, "{h} m"),
            HeightRule::Side => f.write_str("side"),
        }
    }
}

impl LabelTable {
    /// The built-in table (`config/labels.toml`).
    pub fn builtin() -> LabelTable {
        // The built-in file is checked by a unit test; should it ever be broken, run with no
        // rules rather than refuse to start (objects are then named by colour and shape).
        LabelTable::from_toml_str(BUILTIN_LABELS_TOML, "built-in").unwrap_or_else(|error| {
            tracing::error!(%error, "the built-in label table is invalid");
            LabelTable {
                colours: Vec::new(),
                rules: Vec::new(),
            }
        })
    }

    /// Reads a table file.
    pub fn load(path: &Path) -> Result<LabelTable, LabelTableError> {
        let text = std::fs::read_to_string(path).map_err(|e| LabelTableError::Read {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        LabelTable::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses and checks a table; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<LabelTable, LabelTableError> {
        let file: TableFile = toml::from_str(text).map_err(|e| LabelTableError::Parse {
            origin: origin.to_owned(),
            reason: e.message().to_owned(),
        })?;
        let mut problems = Vec::new();
        let mut colours = Vec::new();
        for (name, rgb) in &file.colours {
            let name = name.trim().to_lowercase();
            match hue_signature(rgb.map(f32::from)) {
                Some(signature) if max_minus_min(*rgb) >= 60 => colours.push(ColourRef {
                    name,
                    rgb: *rgb,
                    signature,
                }),
                _ => problems.push(format!(
                    "colour '{name}' {rgb:?} has too little hue to be told from the white \
                     sheet and its black markers (max − min of r, g, b must be ≥ 60)"
                )),
            }
        }
        if colours.len() > 254 {
            problems.push(format!("at most 254 colours, got {}", colours.len()));
        }
        let mut rules = Vec::new();
        for (i, rule) in file.labels.iter().enumerate() {
            let at = format!("labels[{i}]");
            let label = rule.label.trim().to_lowercase();
            if label.is_empty() {
                problems.push(format!("{at}.label: must not be empty"));
            }
            let color = rule.color.trim().to_lowercase();
            let colour = colours.iter().position(|c| c.name == color);
            if colour.is_none() {
                problems.push(format!(
                    "{at}.color: '{color}' is not in [colours] ({})",
                    colours
                        .iter()
                        .map(|c| c.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
            let [min, max] = rule.size_m;
            if !(min.is_finite() && max.is_finite() && min > 0.0 && min <= max && max <= 1.0) {
                problems.push(format!(
                    "{at}.size_m: [{min}, {max}] must be 0 < min ≤ max ≤ 1 metre"
                ));
            }
            let height = match &rule.height_m {
                HeightFile::Metres(h) if h.is_finite() && *h >= 0.0 && *h <= 1.0 => {
                    Some(HeightRule::Fixed(*h))
                }
                HeightFile::Metres(h) => {
                    problems.push(format!("{at}.height_m: {h} must be 0 … 1 metre"));
                    None
                }
                HeightFile::Word(w) if w.trim().eq_ignore_ascii_case("side") => {
                    Some(HeightRule::Side)
                }
                HeightFile::Word(w) => {
                    problems.push(format!(
                        "{at}.height_m: '{w}' must be a number of metres or \"side\""
                    ));
                    None
                }
            };
            if let (Some(colour), Some(height), false) = (colour, height, label.is_empty()) {
                rules.push(LabelRule {
                    label,
                    colour,
                    shape: rule.shape,
                    min_size_m: min,
                    max_size_m: max,
                    height,
                });
            }
        }
        if problems.is_empty() {
            Ok(LabelTable { colours, rules })
        } else {
            Err(LabelTableError::Invalid {
                origin: origin.to_owned(),
                problems: problems.join("; "),
            })
        }
    }

    /// The labels the rules give, in table order, without duplicates.
    pub fn labels(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for rule in &self.rules {
            if !out.contains(&rule.label) {
                out.push(rule.label.clone());
            }
        }
        out
    }

    /// The colour whose hue signature is nearest `signature`, with the distance.
    pub fn nearest_colour(&self, signature: [f32; 3]) -> Option<(usize, f32)> {
        self.colours
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let d = c
                    .signature
                    .iter()
                    .zip(&signature)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f32>()
                    .sqrt();
                (i, d)
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The first rule for an object of colour `colour` (a name of [`LabelTable::colours`]),
    /// measured shape `shape` and longest side `size_m`.
    pub fn rule_for(&self, colour: &str, shape: ShapeClass, size_m: f64) -> Option<&LabelRule> {
        let index = self.colours.iter().position(|c| c.name == colour)?;
        self.rule_index_for(index, shape, size_m)
            .map(|i| &self.rules[i])
    }

    /// Like [`LabelTable::rule_for`] with a colour index; returns the rule's index.
    pub fn rule_index_for(&self, colour: usize, shape: ShapeClass, size_m: f64) -> Option<usize> {
        self.rules.iter().position(|r| {
            r.colour == colour
                && r.shape.accepts(shape)
                && size_m >= r.min_size_m
                && size_m <= r.max_size_m
        })
    }
}

fn max_minus_min(rgb: [u8; 3]) -> u8 {
    let max = rgb[0].max(rgb[1]).max(rgb[2]);
    let min = rgb[0].min(rgb[1]).min(rgb[2]);
    max - min
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_table_parses_and_names_the_default_scene() {
        let t = LabelTable::from_toml_str(BUILTIN_LABELS_TOML, "built-in").unwrap();
        assert!(t.colours.len() >= 9);
        assert_eq!(
            t.labels(),
            [
                "pencil",
                "red cube",
                "blue square",
                "green cylinder",
                "blue cylinder",
                "large box",
                "tray"
            ]
        );
        assert_eq!(
            t.rule_for("blue", ShapeClass::Round, 0.035).unwrap().label,
            "blue cylinder"
        );
        assert_eq!(
            t.rule_for("blue", ShapeClass::Square, 0.045).unwrap().label,
            "blue square"
        );
        assert_eq!(
            t.rule_for("orange", ShapeClass::Square, 0.09)
                .unwrap()
                .label,
            "large box"
        );
        assert!(t.rule_for("cyan", ShapeClass::Square, 0.03).is_none());
    }

    #[test]
    fn hue_signature_ignores_shading_and_white() {
        let red = hue_signature([200.0, 30.0, 30.0]).unwrap();
        let shaded = hue_signature([110.0, 16.5, 16.5]).unwrap();
        let pale = hue_signature([222.0, 137.5, 136.0]).unwrap();
        for s in [shaded, pale] {
            for (a, b) in red.iter().zip(&s) {
                assert!((a - b).abs() < 0.02, "{red:?} vs {s:?}");
            }
        }
        assert!(hue_signature([128.0, 128.0, 128.0]).is_none());
    }

    #[test]
    fn bad_tables_are_refused_with_every_reason() {
        let text = r#"
            [colours]
            red = [200, 30, 30]
            grey = [128, 128, 128]
            [[labels]]
            label = ""
            color = "mauve"
            shape = "square"
            size_m = [0.05, 0.01]
            height_m = "tall"
        "#;
        let err = LabelTable::from_toml_str(text, "lab.toml")
            .unwrap_err()
            .to_string();
        for needle in [
            "lab.toml",
            "colour 'grey'",
            "labels[0].label: must not be empty",
            "labels[0].color: 'mauve' is not in [colours] (red)",
            "labels[0].size_m",
            "labels[0].height_m: 'tall'",
        ] {
            assert!(err.contains(needle), "{needle} missing in: {err}");
        }
        let typo = "[colours]\nred = [200, 30, 30]\n[[labels]]\nlabel='x'\ncolour='red'\n";
        let err = LabelTable::from_toml_str(typo, "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("unknown field `colour`"), "{err}");
    }

    #[test]
    fn shape_classes_from_measurements() {
        assert_eq!(ShapeClass::measure(1.02, 0.79), ShapeClass::Round);
        assert_eq!(ShapeClass::measure(1.02, 0.98), ShapeClass::Square);
        assert_eq!(ShapeClass::measure(2.0, 0.98), ShapeClass::Rectangle);
        assert_eq!(ShapeClass::measure(10.0, 0.97), ShapeClass::Bar);
        assert!(ShapeClass::Box.accepts(ShapeClass::Bar));
        assert!(!ShapeClass::Box.accepts(ShapeClass::Round));
        assert!(ShapeClass::Any.accepts(ShapeClass::Round));
    }
}
