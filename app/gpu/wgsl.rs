//! The WGSL text the program carries: each module's files joined and stripped at compile time of what no compiler
//! reads (line comments, indentation, blank lines) by `wgsl_module!`. The comments are the
//! shaders' documentation, half their bytes and most of their gzipped weight in the page's wasm (the page's budget
//! is 1.5 MB); the files under `shaders/` keep them, and `tests/it/shaders.rs` holds each module to its files.

/// Keeps of `source` each line's text before `//`, trimmed of spaces, tabs and carriage returns on both sides, and
/// only the lines left with text, each ending in `\n`. Writes the kept bytes into `out` when it is long enough
/// (an empty `out` only counts them) and returns how many there are. `const` so that the stripping happens in the
/// compiler; WGSL has no string literals, so `//` always starts a comment.
pub const fn strip_comments(source: &[u8], out: &mut [u8]) -> usize {
    let write = !out.is_empty();
    let mut kept = 0;
    let mut start = 0;
    while start < source.len() {
        let mut end = start;
        while end < source.len() && source[end] != b'\n' {
            end += 1;
        }
        // The line's text before any comment.
        let mut text_end = start;
        while text_end < end && !(source[text_end] == b'/' && text_end + 1 < end && source[text_end + 1] == b'/') {
            text_end += 1;
        }
        let mut first = start;
        while first < text_end && is_blank(source[first]) {
            first += 1;
        }
        while text_end > first && is_blank(source[text_end - 1]) {
            text_end -= 1;
        }
        if first < text_end {
            let mut i = first;
            while i < text_end {
                if write {
                    out[kept] = source[i];
                }
                kept += 1;
                i += 1;
            }
            if write {
                out[kept] = b'\n';
            }
            kept += 1;
        }
        start = end + 1;
    }
    kept
}

const fn is_blank(byte: u8) -> bool {
    matches!(byte, b' ' | b'\t' | b'\r')
}

/// A `&'static str` of WGSL (a `concat!` of `include_str!`s) stripped by [`strip_comments`] at compile time.
macro_rules! wgsl_module {
    ($source:expr) => {{
        const SOURCE: &[u8] = $source.as_bytes();
        const LEN: usize = $crate::gpu::wgsl::strip_comments(SOURCE, &mut []);
        const BYTES: [u8; LEN] = {
            let mut out = [0u8; LEN];
            $crate::gpu::wgsl::strip_comments(SOURCE, &mut out);
            out
        };
        match ::core::str::from_utf8(&BYTES) {
            Ok(text) => text,
            Err(_) => panic!("a shader stripped of its comments is not UTF-8"),
        }
    }};
}
pub(crate) use wgsl_module;
