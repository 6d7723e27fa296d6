//! The `fmuResourceLocation` of fmi2Instantiate: a `file:` URI of the FMU's
//! `resources` folder (RFC 8089), e.g. `file:///tmp/fmu%20x/resources/`,
//! `file:/tmp/fmu%20x/resources` or `file://localhost/tmp/…`.

use std::path::PathBuf;

/// The local path named by `uri`. A plain absolute path is accepted too, as
/// it is (some masters pass one).
pub fn resource_path(uri: &str) -> Result<PathBuf, String> {
    let path = match uri.get(..5) {
        Some(scheme) if scheme.eq_ignore_ascii_case("file:") => file_uri_path(&uri[5..])?,
        _ if uri.starts_with('/') => return Ok(PathBuf::from(uri)),
        _ => return Err(format!("`{uri}` is not a file: URI")),
    };
    if path.contains(['?', '#']) {
        return Err(format!("`{uri}` has a query or fragment; a resource location is a plain file: URI"));
    }
    let bytes = percent_decode(path).map_err(|e| format!("`{uri}`: {e}"))?;
    Ok(path_from_bytes(bytes))
}

/// The path part after `file:`: `///p`, `//localhost/p` or `/p`.
fn file_uri_path(rest: &str) -> Result<&str, String> {
    let Some(authority_and_path) = rest.strip_prefix("//") else {
        return if rest.starts_with('/') {
            Ok(rest)
        } else {
            Err(format!("`file:{rest}` is not an absolute file URI"))
        };
    };
    let split = authority_and_path.find('/').unwrap_or(authority_and_path.len());
    let (host, path) = authority_and_path.split_at(split);
    if !(host.is_empty() || host.eq_ignore_ascii_case("localhost")) {
        return Err(format!("`file:{rest}` names host `{host}`; only local files can be read"));
    }
    if path.is_empty() {
        return Err(format!("`file:{rest}` has no path"));
    }
    Ok(path)
}

fn percent_decode(s: &str) -> Result<Vec<u8>, String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok());
            let byte = hex
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad percent escape at byte {i}"))?;
            out.push(byte);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Ok(out)
}

#[cfg(unix)]
fn path_from_bytes(bytes: Vec<u8>) -> PathBuf {
    use std::os::unix::ffi::OsStringExt;
    PathBuf::from(std::ffi::OsString::from_vec(bytes))
}

#[cfg(not(unix))]
fn path_from_bytes(bytes: Vec<u8>) -> PathBuf {
    PathBuf::from(String::from_utf8_lossy(&bytes).into_owned())
}

#[cfg(test)]
mod tests {
    use super::resource_path;
    use std::path::PathBuf;

    fn ok(uri: &str) -> PathBuf {
        resource_path(uri).unwrap_or_else(|e| panic!("{uri}: {e}"))
    }

    #[test]
    fn three_slash_form_with_percent_encoding() {
        assert_eq!(ok("file:///tmp/my%20fmu/resources/"), PathBuf::from("/tmp/my fmu/resources/"));
        assert_eq!(ok("file:///tmp/a%25b"), PathBuf::from("/tmp/a%b"));
    }

    #[test]
    fn one_slash_form() {
        assert_eq!(ok("file:/tmp/x%5By%5D/resources"), PathBuf::from("/tmp/x[y]/resources"));
    }

    #[test]
    fn localhost_and_scheme_case() {
        assert_eq!(ok("file://localhost/tmp/r"), PathBuf::from("/tmp/r"));
        assert_eq!(ok("FILE:///tmp/r"), PathBuf::from("/tmp/r"));
    }

    #[test]
    fn utf8_escapes_decode_to_the_name() {
        assert_eq!(ok("file:///tmp/%C3%A4%E2%82%AC"), PathBuf::from("/tmp/ä€"));
        assert_eq!(ok("file:///tmp/ä"), PathBuf::from("/tmp/ä"));
    }

    #[test]
    fn plain_absolute_path_is_accepted() {
        assert_eq!(ok("/tmp/plain dir%20#1"), PathBuf::from("/tmp/plain dir%20#1"));
    }

    #[test]
    fn bad_uris_are_rejected_with_a_reason() {
        for uri in [
            "",
            "resources",
            "http://example.com/resources",
            "file://otherhost/tmp/r",
            "file://",
            "file:relative/path",
            "file:///tmp/%zz",
            "file:///tmp/%4",
            "file:///tmp/%",
            "file:///tmp/r?x=1",
            "file:///tmp/r#frag",
        ] {
            let err = resource_path(uri).expect_err(uri);
            assert!(!err.is_empty(), "{uri}");
        }
    }
}
