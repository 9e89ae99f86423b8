//! Checks of text values that several sections share: names and URLs.

/// `Ok` when `name` is 1 to `max` characters of `[A-Za-z0-9_-]`.
pub fn check_name(name: &str, max: usize) -> Result<(), String> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.len() > max {
        return Err(format!(
            "must be at most {max} characters, got {}",
            name.len()
        ));
    }
    if let Some(bad) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
    {
        return Err(format!(
            "{name:?} contains {bad:?}; only letters, digits, '_' and '-' are allowed"
        ));
    }
    Ok(())
}

/// `Ok` when `url` is `<scheme>://<something>` with one of `schemes`.
pub fn check_url(url: &str, schemes: &[&str]) -> Result<(), String> {
    match url.split_once("://") {
        Some((scheme, rest)) if schemes.contains(&scheme) && !rest.is_empty() => Ok(()),
        Some((scheme, _)) if !schemes.contains(&scheme) => Err(format!(
            "{url:?} has scheme {scheme:?}, not one of {}",
            schemes.join(", ")
        )),
        _ => Err(format!("{url:?} is not a URL")),
    }
}
