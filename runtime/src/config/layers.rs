//! The layers of a configuration as figment providers: the built-in defaults, the file, the
//! `ROBOTD_*` environment and the command-line overrides, each named so a problem can say
//! where its value was set.

use super::problems::{DEFAULTS_NAME, ENV_NAME, OVERRIDE_NAME};
use super::{ENV_CONFIG_FILE, ENV_PREFIX, ENV_SEPARATOR};
use figment::value::{Dict, Map, Value};
use figment::{Metadata, Profile, Provider, Source};

/// The built-in defaults `text`, the first layer.
pub(super) fn defaults_layer(text: &str) -> Layer {
    Layer::toml(text.to_owned(), Metadata::named(DEFAULTS_NAME))
}

/// A TOML text with the metadata we want errors to show.
pub(super) struct Layer {
    text: String,
    metadata: Metadata,
}

impl Layer {
    pub(super) fn toml(text: String, metadata: Metadata) -> Self {
        Layer { text, metadata }
    }
}

impl Provider for Layer {
    fn metadata(&self) -> Metadata {
        self.metadata.clone()
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        use figment::providers::{Format, Toml};
        Toml::string(&self.text).data().map_err(|error| {
            let place = match self.metadata.source.as_ref().and_then(Source::file_path) {
                Some(path) => format!("config file {}", path.display()),
                None => self.metadata.name.to_string(),
            };
            figment::Error::from(format!("{place} is not valid TOML: {}", error.kind))
        })
    }
}

/// `ROBOTD_*` variables, nested on `__`.
pub(super) struct EnvLayer {
    vars: Vec<(String, String)>,
}

impl EnvLayer {
    pub(super) fn new(vars: impl Iterator<Item = (String, String)>) -> Self {
        let vars = vars
            .filter(|(name, _)| {
                name.len() > ENV_PREFIX.len()
                    && name.is_char_boundary(ENV_PREFIX.len())
                    && name[..ENV_PREFIX.len()].eq_ignore_ascii_case(ENV_PREFIX)
                    && !name.eq_ignore_ascii_case(ENV_CONFIG_FILE)
            })
            .collect();
        EnvLayer { vars }
    }
}

impl Provider for EnvLayer {
    fn metadata(&self) -> Metadata {
        Metadata::named(ENV_NAME).interpolater(|_: &Profile, keys: &[&str]| {
            let keys: Vec<String> = keys.iter().map(|k| k.to_ascii_uppercase()).collect();
            format!("{ENV_PREFIX}{}", keys.join(ENV_SEPARATOR))
        })
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        let mut dict = Dict::new();
        for (name, value) in &self.vars {
            let segments: Vec<String> = name[ENV_PREFIX.len()..]
                .split(ENV_SEPARATOR)
                .map(|s| s.to_ascii_lowercase())
                .collect();
            if segments.iter().any(|s| s.is_empty() || s.contains('.')) {
                return Err(figment::Error::from(format!(
                    "environment variable {name} does not name a key: write ROBOTD_<SECTION>__<KEY>, e.g. ROBOTD_HTTP__BIND"
                )));
            }
            insert(&mut dict, &segments, parse_value(value));
        }
        Ok(Profile::Default.collect(dict))
    }
}

/// Command-line `key=value` overrides.
pub(super) struct OverrideLayer(pub(super) Vec<(String, String)>);

impl Provider for OverrideLayer {
    fn metadata(&self) -> Metadata {
        Metadata::named(OVERRIDE_NAME)
    }

    fn data(&self) -> Result<Map<Profile, Dict>, figment::Error> {
        let mut dict = Dict::new();
        for (key, value) in &self.0 {
            let segments: Vec<String> = key.trim().split('.').map(str::to_owned).collect();
            if segments.iter().any(String::is_empty) {
                return Err(figment::Error::from(format!(
                    "override {key:?}={value:?} does not name a key: write e.g. http.bind=0.0.0.0:8000"
                )));
            }
            insert(&mut dict, &segments, parse_value(value));
        }
        Ok(Profile::Default.collect(dict))
    }
}

/// Reads an environment/override value like a TOML value (number, bool, list, table), else
/// as text.
///
/// figment 0.10's value parser slices a quoted string at a character count instead of a byte
/// offset, and panics when a backslash follows a non-ASCII character (`"é\n"`). Such a value
/// goes to the `toml` parser instead, and is text when that refuses it.
fn parse_value(value: &str) -> Value {
    if value.contains('\\') && !value.is_ascii() {
        return parse_with_toml(value).unwrap_or_else(|| Value::from(value.to_owned()));
    }
    match value.parse::<Value>() {
        Ok(value) => value,
        Err(never) => match never {},
    }
}

/// `value` as the right-hand side of a TOML `key = value` line, when it is exactly one value.
fn parse_with_toml(value: &str) -> Option<Value> {
    if value.contains(['\n', '\r']) {
        return None;
    }
    let mut table: toml::Table = format!("value = {value}").parse().ok()?;
    Value::serialize(table.remove("value")?).ok()
}

/// Sets `segments` (a key path) in `dict` to `value`, merging with what is already there.
fn insert(dict: &mut Dict, segments: &[String], value: Value) {
    match segments {
        [] => {}
        [last] => {
            dict.insert(last.clone(), value);
        }
        [first, rest @ ..] => {
            let child = dict
                .entry(first.clone())
                .or_insert_with(|| Value::from(Dict::new()));
            if child.as_dict().is_none() {
                *child = Value::from(Dict::new());
            }
            if let Value::Dict(_, child) = child {
                insert(child, rest, value);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_backslash_after_non_ascii_text_is_read_without_panicking() {
        // figment alone panics on each of these.
        assert_eq!(parse_value("\"é\\n\"").as_str(), Some("é\n"));
        assert_eq!(
            parse_value("\"\u{10511}\\\u{1cc4}").as_str(),
            Some("\"\u{10511}\\\u{1cc4}")
        );
        let list = parse_value("[\"é\\t\", 2]");
        let items = list.as_array().expect("a list");
        assert_eq!(items[0].as_str(), Some("é\t"));
        assert_eq!(items[1].to_i128(), Some(2));
        assert_eq!(parse_value("C:\\Users\\é").as_str(), Some("C:\\Users\\é"));
        assert_eq!(
            parse_value("\"é\\\"\nx = 1").as_str(),
            Some("\"é\\\"\nx = 1")
        );
    }

    #[test]
    fn plain_values_still_read_as_toml() {
        assert_eq!(parse_value("42").to_u128(), Some(42));
        assert_eq!(parse_value("true").to_bool(), Some(true));
        assert_eq!(parse_value("\"a\\nb\"").as_str(), Some("a\nb"));
        assert_eq!(parse_value("héllo").as_str(), Some("héllo"));
    }
}
