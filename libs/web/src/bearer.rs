//! The bearer token of a request.

use axum::http::{header, HeaderMap};

/// The bearer token a request presents: `Authorization: Bearer <token>`, else
/// `?access_token=<token>` in its URL `query` (what a browser can send for a page, an image
/// or an event stream). The HTTP guard checks it; the MCP edge binds sessions to it.
pub fn bearer_token<'a>(headers: &'a HeaderMap, query: Option<&'a str>) -> Option<&'a str> {
    headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .or_else(|| {
            query?
                .split('&')
                .find_map(|pair| pair.strip_prefix("access_token="))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_wins_over_the_query_and_other_schemes_are_not_tokens() {
        let mut headers = HeaderMap::new();
        assert_eq!(
            bearer_token(&headers, Some("a=1&access_token=q")),
            Some("q")
        );
        assert_eq!(bearer_token(&headers, Some("a=1")), None);
        headers.insert(header::AUTHORIZATION, "Bearer h".parse().unwrap());
        assert_eq!(bearer_token(&headers, Some("access_token=q")), Some("h"));
        headers.insert(header::AUTHORIZATION, "Basic dXNlcg==".parse().unwrap());
        assert_eq!(bearer_token(&headers, None), None);
    }
}
