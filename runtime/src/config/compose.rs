//! The whole configuration from its sections: [`Composed`] (written for you by
//! [`compose_config!`](crate::compose_config)) and [`load`], which layers, reads and checks it.

use super::layers::{defaults_layer, EnvLayer, Layer, OverrideLayer};
use super::problems::{origin_of, problem_from_figment, FILE_NAME};
use super::{ConfigError, LoadOptions, Problem};
use figment::value::Dict;
use figment::{Figment, Metadata, Source};
use serde::de::DeserializeOwned;

/// A configuration made of [`Section`](super::Section)s, one per top-level table.
pub trait Composed: DeserializeOwned {
    /// The top-level tables, in file order.
    const SECTIONS: &'static [&'static str];

    /// Reads each section present in the layers on its own, adding its problems.
    fn read_sections(reader: &mut SectionReader<'_>);

    /// Every problem of values serde accepted, as `(dotted key, reason)`: each section's
    /// checks, then the checks across sections. May fill in values derived from others.
    fn finish(&mut self, problems: &mut Vec<(String, String)>);
}

/// Reads parts of the layers on their own, to report one problem per section.
pub struct SectionReader<'a> {
    figment: &'a Figment,
    top: &'a Dict,
    problems: &'a mut Vec<Problem>,
}

impl SectionReader<'_> {
    /// Reads the table at `key` (if present) alone as a `T`, adding its problems.
    pub fn read<T: DeserializeOwned>(&mut self, key: &str) {
        if !key.contains('.') && !self.top.contains_key(key) {
            return;
        }
        if let Err(error) = self.figment.focus(key).extract::<T>() {
            self.problems.extend(
                error
                    .into_iter()
                    .map(|error| problem_from_figment(self.figment, key, error)),
            );
        }
    }

    /// Reads each entry of the table at `key` alone as a `T` (a table that is not a table is
    /// read as a whole).
    pub fn read_each<T: DeserializeOwned>(&mut self, key: &str) {
        match self.top.get(key).map(|table| table.as_dict()) {
            Some(Some(entries)) => {
                let names: Vec<String> = entries
                    .keys()
                    .filter(|name| !name.contains('.'))
                    .cloned()
                    .collect();
                for name in names {
                    self.read::<T>(&format!("{key}.{name}"));
                }
            }
            Some(None) => self.read::<std::collections::BTreeMap<String, T>>(key),
            None => {}
        }
    }
}

/// Loads a configuration: the `defaults` TOML text, then `options.file`, then the `env`
/// pairs whose name starts with `ROBOTD_`, then `options.overrides`; then reads and checks
/// it, reporting every problem with its origin.
pub fn load<C, I, K, V>(defaults: &str, options: LoadOptions, env: I) -> Result<C, ConfigError>
where
    C: Composed,
    I: IntoIterator<Item = (K, V)>,
    K: Into<String>,
    V: Into<String>,
{
    let mut figment = Figment::new().merge(defaults_layer(defaults));
    if let Some(path) = &options.file {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::ReadFile {
            path: path.clone(),
            source,
        })?;
        figment = figment.merge(Layer::toml(
            text,
            Metadata::from(FILE_NAME, Source::File(path.clone())),
        ));
    }
    let env = EnvLayer::new(env.into_iter().map(|(k, v)| (k.into(), v.into())));
    figment = figment.merge(env).merge(OverrideLayer(options.overrides));
    extract(&figment)
}

/// Checks a configuration changed in code: [`Composed::finish`]'s problems, without origins.
pub fn validate<C: Composed + Clone>(config: &C) -> Result<(), ConfigError> {
    let mut found = Vec::new();
    config.clone().finish(&mut found);
    if found.is_empty() {
        return Ok(());
    }
    Err(ConfigError::Invalid {
        problems: found
            .into_iter()
            .map(|(key, reason)| Problem {
                key,
                reason,
                origin: None,
            })
            .collect(),
    })
}

/// Extracts and checks, turning every error into a [`Problem`] with its origin.
fn extract<C: Composed>(figment: &Figment) -> Result<C, ConfigError> {
    let mut config: C = figment.extract().map_err(|error| ConfigError::Invalid {
        problems: deserialization_problems::<C>(figment, error),
    })?;
    let mut found = Vec::new();
    config.finish(&mut found);
    let problems: Vec<Problem> = found
        .into_iter()
        .map(|(key, reason)| {
            let origin = origin_of(figment, &key, None);
            Problem {
                key,
                reason,
                origin,
            }
        })
        .collect();
    if problems.is_empty() {
        Ok(config)
    } else {
        Err(ConfigError::Invalid { problems })
    }
}

/// serde stops at the first error of a struct, so after a failed extraction each section
/// (and each actor) is read again on its own: the user learns about one problem per section
/// instead of one per start-up.
fn deserialization_problems<C: Composed>(figment: &Figment, first: figment::Error) -> Vec<Problem> {
    let top: Dict = match figment.extract() {
        Ok(top) => top,
        // A layer that does not parse (TOML syntax) is reported alone.
        Err(error) => {
            return error
                .into_iter()
                .map(|error| problem_from_figment(figment, "", error))
                .collect()
        }
    };
    let mut problems = Vec::new();
    for key in top
        .keys()
        .filter(|key| !C::SECTIONS.contains(&key.as_str()))
    {
        problems.push(Problem {
            key: key.clone(),
            reason: format!(
                "unknown section; the top level accepts {}",
                C::SECTIONS.join(", ")
            ),
            origin: origin_of(figment, key, None),
        });
    }
    C::read_sections(&mut SectionReader {
        figment,
        top: &top,
        problems: &mut problems,
    });
    if problems.is_empty() {
        // Not found section by section (e.g. a missing section): report what serde said.
        problems = first
            .into_iter()
            .map(|error| problem_from_figment(figment, "", error))
            .collect();
    }
    problems
}

/// Declares the whole configuration from its sections: the struct (serde, unknown sections
/// refused), [`Composed`], `Config::load`, `Config::load_with_env`, `Config::validate` and
/// `Default` (the built-in defaults alone).
///
/// ```
/// use robotd_runtime::config::{BusConfig, ServiceConfig};
///
/// const DEFAULTS: &str = "[service]\nname = \"demo\"\nworker_threads = 1\n[bus]\nnamespace = \"demo\"\n\
///                         request_timeout_ms = 1000\nframe_subscriber_buffer = 2\n";
///
/// robotd_runtime::compose_config! {
///     /// A configuration of two sections.
///     pub struct DemoConfig {
///         /// `[service]`
///         service: ServiceConfig,
///         /// `[bus]`
///         bus: BusConfig,
///     }
///     defaults = DEFAULTS;
///     finish = |_config, _problems| {};
/// }
///
/// let config = DemoConfig::default();
/// assert_eq!(config.bus.namespace, "demo");
/// let bad = robotd_runtime::config::LoadOptions {
///     file: None,
///     overrides: vec![("bus.request_timeout_ms".into(), "0".into())],
/// };
/// let error = DemoConfig::load_with_env(bad, Vec::<(String, String)>::new()).unwrap_err();
/// assert!(error.to_string().contains("bus.request_timeout_ms: must be greater than 0 ms"));
/// ```
#[macro_export]
macro_rules! compose_config {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
        defaults = $defaults:expr;
        finish = $finish:expr;
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: $ty, )*
        }

        impl $crate::config::Composed for $name {
            const SECTIONS: &'static [&'static str] = &[$(stringify!($field)),*];

            fn read_sections(reader: &mut $crate::config::SectionReader<'_>) {
                $( <$ty as $crate::config::Section>::read_problems(reader, stringify!($field)); )*
            }

            fn finish(&mut self, problems: &mut Vec<(String, String)>) {
                $(
                    $crate::config::Section::check(
                        &self.$field,
                        &mut $crate::config::Checks::new(stringify!($field), problems),
                    );
                )*
                let finish: fn(&mut $name, &mut Vec<(String, String)>) = $finish;
                finish(self, problems);
            }
        }

        impl $name {
            /// Loads the configuration: the built-in defaults, then `options.file`, then the
            /// process's `ROBOTD_*` environment variables, then `options.overrides`; then
            /// checks it.
            pub fn load(
                options: $crate::config::LoadOptions,
            ) -> Result<Self, $crate::config::ConfigError> {
                Self::load_with_env(
                    options,
                    std::env::vars_os().filter_map(|(k, v)| {
                        Some((k.into_string().ok()?, v.into_string().ok()?))
                    }),
                )
            }

            /// As `load`, with the environment given explicitly instead of read from the
            /// process (tests use this so they never touch, or race on, the real
            /// environment). Pairs whose name does not start with `ROBOTD_` are ignored.
            pub fn load_with_env<I, K, V>(
                options: $crate::config::LoadOptions,
                env: I,
            ) -> Result<Self, $crate::config::ConfigError>
            where
                I: IntoIterator<Item = (K, V)>,
                K: Into<String>,
                V: Into<String>,
            {
                $crate::config::load($defaults, options, env)
            }

            /// Checks ranges and formats serde cannot express; `load` already does this: call
            /// it after changing a configuration in code.
            pub fn validate(&self) -> Result<(), $crate::config::ConfigError> {
                $crate::config::validate(self)
            }
        }

        impl Default for $name {
            /// The built-in defaults alone: no file, environment or overrides.
            fn default() -> Self {
                static DEFAULT: std::sync::OnceLock<$name> = std::sync::OnceLock::new();
                DEFAULT
                    .get_or_init(|| {
                        match Self::load_with_env(
                            $crate::config::LoadOptions::default(),
                            Vec::<(String, String)>::new(),
                        ) {
                            Ok(config) => config,
                            // Checked by a test of the composing crate; cannot depend on
                            // outside input.
                            Err(error) => panic!("the built-in defaults are invalid: {error}"),
                        }
                    })
                    .clone()
            }
        }
    };
}
