//! The `fmuResourceLocation` of fmi2Instantiate: a `file:` URI of the FMU's
//! `resources` folder (RFC 8089), e.g. `file:///tmp/fmu%20x/resources/`,
//! `file:/tmp/fmu%20x/resources` or `file://localhost/tmp/…`; on Windows
//! `file:///C:/dir/resources` (the drive letter follows the root slash, which
//! is not part of the local path) or `file://server/share/…` (a UNC path).
//! On macOS the Unix forms: `file:///Users/…`, `file://localhost/Users/…`,
//! `file:///private/var/folders/…` (a temporary directory).
//!
//! Parsed here rather than by a URI crate, which handled these forms worse
//! (tried on the inputs of the tests below): `url` (WHATWG) accepts `file://`
//! and `file:relative/path`, keeps a bad escape such as `%zz` as text, ignores
//! a query or fragment, and turns `file:///C:/x` into a Windows path only when
//! compiled for Windows, so those forms could not be tested on Linux; it also
//! brings IDNA's Unicode tables into the FMU binary. `fluent-uri` (RFC
//! 3986/3987) refuses unescaped spaces and backslashes, which a sloppy master
//! may send and this parser passes on as written, and would leave the
//! drive-letter, UNC and plain-path rules to this file anyway. `percent-encoding` keeps bad escapes as text too.

use std::path::PathBuf;

/// Which path syntax a URI is turned into. Kept apart from the host so that
/// the Windows forms are tested on every platform.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PathSyntax {
    /// `/dir/file`.
    Unix,
    /// `C:/dir/file` or `//server/share/file` (Windows accepts `/` as separator).
    Windows,
}

impl PathSyntax {
    /// The syntax of the platform this library runs on.
    pub(crate) const HOST: PathSyntax = if cfg!(windows) { PathSyntax::Windows } else { PathSyntax::Unix };
}

/// The local path named by `uri`. A plain absolute path is accepted too, as
/// it is (some masters pass one).
pub fn resource_path(uri: &str) -> Result<PathBuf, String> {
    let bytes = local_path(uri, PathSyntax::HOST)?;
    path_from_bytes(bytes).map_err(|e| format!("`{uri}`: {e}"))
}

/// The bytes of the local path `uri` names in the given path syntax.
pub(crate) fn local_path(uri: &str, syntax: PathSyntax) -> Result<Vec<u8>, String> {
    let path = match uri.get(..5) {
        Some(scheme) if scheme.eq_ignore_ascii_case("file:") => file_uri_path(&uri[5..], syntax)?,
        _ if is_absolute(uri, syntax) => return Ok(uri.as_bytes().to_vec()),
        _ => return Err(format!("`{uri}` is not a file: URI")),
    };
    if path.contains(['?', '#']) {
        return Err(format!("`{uri}` has a query or fragment; a resource location is a plain file: URI"));
    }
    let mut bytes = percent_decode(&path).map_err(|e| format!("`{uri}`: {e}"))?;
    if syntax == PathSyntax::Windows && bytes.get(1..).is_some_and(starts_with_drive) {
        bytes.remove(0); // `/C:/dir` → `C:/dir`
    }
    Ok(bytes)
}

/// A plain path that a master may pass instead of a URI.
fn is_absolute(path: &str, syntax: PathSyntax) -> bool {
    match syntax {
        PathSyntax::Unix => path.starts_with('/'),
        PathSyntax::Windows => {
            (path.len() > 2 && starts_with_drive(path.as_bytes())) || path.starts_with("\\\\") || path.starts_with("//")
        }
    }
}

/// `C:/…`, `C:\…` (or `C:` alone).
fn starts_with_drive(p: &[u8]) -> bool {
    p.len() >= 2 && p[0].is_ascii_alphabetic() && p[1] == b':' && matches!(p.get(2), None | Some(b'/' | b'\\'))
}

/// The path part after `file:`: `///p`, `//localhost/p` or `/p`; on Windows
/// also `//server/share/p`, which becomes the UNC path `//server/share/p`.
fn file_uri_path(rest: &str, syntax: PathSyntax) -> Result<String, String> {
    let Some(authority_and_path) = rest.strip_prefix("//") else {
        return if rest.starts_with('/') {
            Ok(rest.to_string())
        } else {
            Err(format!("`file:{rest}` is not an absolute file URI"))
        };
    };
    let split = authority_and_path.find('/').unwrap_or(authority_and_path.len());
    let (host, path) = authority_and_path.split_at(split);
    if path.is_empty() {
        return Err(format!("`file:{rest}` has no path"));
    }
    if host.is_empty() || host.eq_ignore_ascii_case("localhost") {
        return Ok(path.to_string());
    }
    match syntax {
        PathSyntax::Windows => Ok(format!("//{host}{path}")),
        PathSyntax::Unix => Err(format!("`file:{rest}` names host `{host}`; only local files can be read")),
    }
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
fn path_from_bytes(bytes: Vec<u8>) -> Result<PathBuf, String> {
    use std::os::unix::ffi::OsStringExt;
    Ok(PathBuf::from(std::ffi::OsString::from_vec(bytes)))
}

/// Windows names are Unicode: the decoded bytes must be UTF-8.
#[cfg(not(unix))]
fn path_from_bytes(bytes: Vec<u8>) -> Result<PathBuf, String> {
    String::from_utf8(bytes).map(PathBuf::from).map_err(|_| "the decoded path is not UTF-8".to_string())
}

#[cfg(test)]
mod tests {
    use super::{local_path, resource_path, PathSyntax};
    use std::path::PathBuf;

    /// The path in Unix syntax (the tests of both syntaxes run on every host).
    fn ok(uri: &str) -> PathBuf {
        let bytes = local_path(uri, PathSyntax::Unix).unwrap_or_else(|e| panic!("{uri}: {e}"));
        PathBuf::from(String::from_utf8(bytes).expect("UTF-8"))
    }

    #[test]
    fn resource_path_uses_the_host_syntax() {
        let path = resource_path("file:///C:/dir/my%20fmu/resources").expect("a valid URI");
        let expected = if cfg!(windows) { "C:/dir/my fmu/resources" } else { "/C:/dir/my fmu/resources" };
        assert_eq!(path, PathBuf::from(expected));
    }

    #[test]
    fn three_slash_form_with_percent_encoding() {
        assert_eq!(ok("file:///tmp/my%20fmu/resources/"), PathBuf::from("/tmp/my fmu/resources/"));
        assert_eq!(ok("file:///tmp/a%25b"), PathBuf::from("/tmp/a%b"));
    }

    /// A master that puts the path into the URI unescaped still works.
    #[test]
    fn unescaped_characters_pass_as_they_are() {
        assert_eq!(ok("file:///tmp/my fmu [2]/resources"), PathBuf::from("/tmp/my fmu [2]/resources"));
        assert_eq!(windows("file:///C:/Program Files/fmu/resources"), "C:/Program Files/fmu/resources");
        assert_eq!(windows("file:///C:\\dir\\resources"), "C:\\dir\\resources");
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
            let err = local_path(uri, PathSyntax::Unix).expect_err(uri);
            assert!(!err.is_empty(), "{uri}");
        }
    }

    fn windows(uri: &str) -> String {
        let bytes = local_path(uri, PathSyntax::Windows).unwrap_or_else(|e| panic!("{uri}: {e}"));
        String::from_utf8(bytes).expect("UTF-8")
    }

    #[test]
    fn windows_drive_letter_follows_the_root_slash() {
        assert_eq!(windows("file:///C:/dir/resources"), "C:/dir/resources");
        assert_eq!(
            windows("file:///c:/Users/A%20B/AppData/Local/Temp/fmu/resources/"),
            "c:/Users/A B/AppData/Local/Temp/fmu/resources/"
        );
        assert_eq!(windows("file:/D:/x"), "D:/x");
        assert_eq!(windows("file://localhost/C:/x"), "C:/x");
        assert_eq!(windows("FILE:///C:"), "C:");
        assert_eq!(windows("file:///C:/%C3%A4"), "C:/ä");
    }

    #[test]
    fn windows_host_is_a_unc_share_and_plain_paths_pass() {
        assert_eq!(windows("file://server/share/fmu/resources"), "//server/share/fmu/resources");
        assert_eq!(windows("C:\\dir\\resources"), "C:\\dir\\resources");
        assert_eq!(windows("C:/dir/resources"), "C:/dir/resources");
        assert_eq!(windows("\\\\server\\share\\r"), "\\\\server\\share\\r");
    }

    #[test]
    fn windows_keeps_a_leading_slash_that_is_no_drive() {
        // `/Cx/…` or `/1:/…` is no drive: the path stays rooted on the current drive.
        assert_eq!(windows("file:///Cx/r"), "/Cx/r");
        assert_eq!(windows("file:///1:/r"), "/1:/r");
    }

    #[test]
    fn windows_rejects_what_is_no_absolute_file_uri() {
        for uri in [
            "",
            "resources",
            "C:",
            "dir\\r",
            "http://example.com/r",
            "file://",
            "file:C:/x",
            "file:///C:/%zz",
            "file:///C:/r?x=1",
        ] {
            let err = local_path(uri, PathSyntax::Windows).expect_err(uri);
            assert!(!err.is_empty(), "{uri}");
        }
    }

    /// The forms a master on macOS passes (fmpy's `Path.as_uri()` of a temporary
    /// directory under `/private/var/folders`, OMSimulator's and FMPy's GUI's
    /// `file:///Users/…`, the `localhost` form); macOS paths are Unix paths, so
    /// the host syntax there is `PathSyntax::Unix`, tested here on Linux.
    #[test]
    fn macos_forms_are_unix_paths() {
        assert_eq!(
            ok("file:///Users/jane/Models/StickSlip/resources"),
            PathBuf::from("/Users/jane/Models/StickSlip/resources")
        );
        assert_eq!(
            ok("file://localhost/Users/jane/Models/StickSlip/resources/"),
            PathBuf::from("/Users/jane/Models/StickSlip/resources/")
        );
        assert_eq!(
            ok("file:///private/var/folders/7x/k2_5t9_n0bq3_h9c1d4w8r6m0000gn/T/tmpa1b2c3d4/resources"),
            PathBuf::from("/private/var/folders/7x/k2_5t9_n0bq3_h9c1d4w8r6m0000gn/T/tmpa1b2c3d4/resources")
        );
        assert_eq!(
            ok("file:///Users/Jane%20Doe/My%20FMUs/resources"),
            PathBuf::from("/Users/Jane Doe/My FMUs/resources")
        );
        assert_eq!(ok("file:/Users/jane/r"), PathBuf::from("/Users/jane/r"));
        assert_eq!(ok("/Users/jane/Models/resources"), PathBuf::from("/Users/jane/Models/resources"));
        // The volume of an external disk.
        assert_eq!(ok("file:///Volumes/Data%201/fmu/resources"), PathBuf::from("/Volumes/Data 1/fmu/resources"));
    }

    /// macOS's file system stores names decomposed (NFD: `a` + U+0308 for `ä`),
    /// and a master encodes the name's bytes as they are: they must reach the
    /// file system unchanged, not recomposed.
    #[test]
    fn macos_decomposed_names_pass_byte_for_byte() {
        let bytes = local_path("file:///Users/j%C3%BCrgen/Mo%CC%88bel/resources", PathSyntax::Unix).expect("valid");
        assert_eq!(bytes, "/Users/jürgen/Mo\u{308}bel/resources".as_bytes());
    }

    #[test]
    fn macos_rejects_a_remote_host() {
        for uri in ["file://jane-mbp.local/Users/jane/r", "file://Users/jane/r"] {
            assert!(local_path(uri, PathSyntax::Unix).is_err(), "{uri}");
        }
    }

    #[test]
    fn unix_does_not_strip_a_drive_like_first_component() {
        assert_eq!(ok("file:///C:/x"), PathBuf::from("/C:/x"));
    }
}
