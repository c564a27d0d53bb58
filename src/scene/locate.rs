//! Maps a field path such as `objects[2].crown.radius_x_m` back to a line and column of the RON
//! text, so that validation errors found after parsing still name the place in the file.
//!
//! The scanner understands RON's nesting (`()`, `[]`, `{}`), strings, chars and comments; it is
//! deliberately forgiving: if a path cannot be followed it returns the deepest place it reached.

/// One step of a field path.
#[derive(Debug, Clone, PartialEq)]
pub enum Seg {
    /// A struct field or map key (keys are matched with or without quotes).
    Field(String),
    /// The n-th element of a list or the n-th positional value.
    Index(usize),
}

/// Parses `a.b[3].c` or `optics["leaf"]` into segments.
pub fn parse_path(path: &str) -> Vec<Seg> {
    let mut segs = Vec::new();
    let mut cur = String::new();
    let mut chars = path.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '.' => {
                if !cur.is_empty() {
                    segs.push(Seg::Field(std::mem::take(&mut cur)));
                }
            }
            '[' => {
                if !cur.is_empty() {
                    segs.push(Seg::Field(std::mem::take(&mut cur)));
                }
                let mut inner = String::new();
                for d in chars.by_ref() {
                    if d == ']' {
                        break;
                    }
                    inner.push(d);
                }
                let inner = inner.trim_matches('"');
                match inner.parse::<usize>() {
                    Ok(i) => segs.push(Seg::Index(i)),
                    Err(_) => segs.push(Seg::Field(inner.to_string())),
                }
            }
            _ => cur.push(c),
        }
    }
    if !cur.is_empty() {
        segs.push(Seg::Field(cur));
    }
    segs
}

#[derive(Debug, Clone, Copy)]
struct Tok {
    pos: usize,
    kind: TokKind,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum TokKind {
    Open,
    Close,
    Comma,
    Colon,
    Word(usize, usize),
    Str(usize, usize),
}

fn tokenize(src: &str) -> Vec<Tok> {
    let b = src.as_bytes();
    let mut toks = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        match c {
            b'/' if i + 1 < b.len() && b[i + 1] == b'/' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if i + 1 < b.len() && b[i + 1] == b'*' => {
                i += 2;
                while i + 1 < b.len() && !(b[i] == b'*' && b[i + 1] == b'/') {
                    i += 1;
                }
                i += 2;
            }
            b'"' => {
                let start = i;
                i += 1;
                while i < b.len() && b[i] != b'"' {
                    if b[i] == b'\\' {
                        i += 1;
                    }
                    i += 1;
                }
                toks.push(Tok {
                    pos: start,
                    kind: TokKind::Str(start + 1, i.min(b.len())),
                });
                i += 1;
            }
            b'(' | b'[' | b'{' => {
                toks.push(Tok {
                    pos: i,
                    kind: TokKind::Open,
                });
                i += 1;
            }
            b')' | b']' | b'}' => {
                toks.push(Tok {
                    pos: i,
                    kind: TokKind::Close,
                });
                i += 1;
            }
            b',' => {
                toks.push(Tok {
                    pos: i,
                    kind: TokKind::Comma,
                });
                i += 1;
            }
            b':' => {
                toks.push(Tok {
                    pos: i,
                    kind: TokKind::Colon,
                });
                i += 1;
            }
            c if c.is_ascii_whitespace() => i += 1,
            _ => {
                let start = i;
                while i < b.len() {
                    let d = b[i];
                    if d.is_ascii_whitespace() || b"()[]{},:\"".contains(&d) {
                        break;
                    }
                    i += 1;
                }
                toks.push(Tok {
                    pos: start,
                    kind: TokKind::Word(start, i),
                });
            }
        }
    }
    toks
}

/// Byte offset → (line, column), both 1-based.
pub fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(src.len());
    let before = &src[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rfind('\n').map_or(offset, |p| offset - p - 1) + 1;
    (line, col)
}

/// Finds the line and column of `path` in the RON text `src`.
pub fn locate(src: &str, path: &str) -> Option<(usize, usize)> {
    let toks = tokenize(src);
    let segs = parse_path(path);
    // Current range: token indices (start, end) of the *contents* of a value.
    let (mut lo, mut hi) = (0usize, toks.len());
    let mut best = None;
    for seg in &segs {
        let mut retries = 0;
        'retry: loop {
            // Skip an enum/struct name and enter the first open bracket of the value.
            let mut k = lo;
            while k < hi && !matches!(toks[k].kind, TokKind::Open) {
                k += 1;
            }
            if k >= hi {
                return best.map(|p| line_col(src, p));
            }
            let inner_lo = k + 1;
            let inner_hi = matching_close(&toks, k).unwrap_or(hi).min(hi);
            // Split the inner range into depth-0 elements.
            let mut elems = Vec::new();
            let mut depth = 0i32;
            let mut start = inner_lo;
            for (t, tok) in toks.iter().enumerate().take(inner_hi).skip(inner_lo) {
                match tok.kind {
                    TokKind::Open => depth += 1,
                    TokKind::Close => depth -= 1,
                    TokKind::Comma if depth == 0 => {
                        elems.push((start, t));
                        start = t + 1;
                    }
                    _ => {}
                }
            }
            if start < inner_hi {
                elems.push((start, inner_hi));
            }
            let found = match seg {
                Seg::Index(i) => elems.get(*i).copied(),
                Seg::Field(name) => elems.iter().copied().find(|&(a, b)| {
                    b > a + 1
                        && toks[a + 1].kind == TokKind::Colon
                        && match toks[a].kind {
                            TokKind::Word(s, e) | TokKind::Str(s, e) => &src[s..e] == name,
                            _ => false,
                        }
                }),
            };
            match found {
                Some((a, b)) => {
                    best = Some(toks[a].pos);
                    lo = if matches!(seg, Seg::Field(_)) {
                        a + 2
                    } else {
                        a
                    };
                    hi = b;
                    if lo >= hi {
                        return best.map(|p| line_col(src, p));
                    }
                    break 'retry;
                }
                // A newtype variant `Tree((…))`: descend into the single inner value and retry.
                None if elems.len() == 1
                    && retries < 2
                    && toks[elems[0].0].kind == TokKind::Open =>
                {
                    lo = elems[0].0;
                    hi = elems[0].1;
                    retries += 1;
                }
                None => return best.map(|p| line_col(src, p)),
            }
        }
    }
    best.map(|p| line_col(src, p))
}

/// The first key that appears twice in the map of the top-level field `field` (e.g.
/// `optics`), with the line/column of both occurrences; `None` when every key is unique or the
/// field is not found. (Serde keeps the last of two equal map keys without a word.)
pub fn duplicate_key(src: &str, field: &str) -> Option<(String, (usize, usize), (usize, usize))> {
    let toks = tokenize(src);
    // The outermost value: skip a struct name, enter its bracket.
    let open = toks.iter().position(|t| t.kind == TokKind::Open)?;
    let close = matching_close(&toks, open).unwrap_or(toks.len());
    let mut depth = 0i32;
    let mut map_open = None;
    for k in open + 1..close {
        match toks[k].kind {
            TokKind::Open => depth += 1,
            TokKind::Close => depth -= 1,
            TokKind::Word(s, e)
                if depth == 0
                    && &src[s..e] == field
                    && toks.get(k + 1).map(|t| t.kind) == Some(TokKind::Colon) =>
            {
                map_open = (k + 2..close).find(|&j| toks[j].kind == TokKind::Open);
                break;
            }
            _ => {}
        }
    }
    let m = map_open?;
    let m_close = matching_close(&toks, m).unwrap_or(toks.len());
    let mut seen: Vec<(&str, usize)> = Vec::new();
    let mut depth = 0i32;
    let mut at_start = true;
    for k in m + 1..m_close {
        match toks[k].kind {
            TokKind::Open => depth += 1,
            TokKind::Close => depth -= 1,
            TokKind::Comma if depth == 0 => {
                at_start = true;
                continue;
            }
            TokKind::Str(s, e) | TokKind::Word(s, e)
                if depth == 0
                    && at_start
                    && toks.get(k + 1).map(|t| t.kind) == Some(TokKind::Colon) =>
            {
                let key = &src[s..e];
                if let Some(&(_, first)) = seen.iter().find(|(n, _)| *n == key) {
                    return Some((
                        key.to_string(),
                        line_col(src, first),
                        line_col(src, toks[k].pos),
                    ));
                }
                seen.push((key, toks[k].pos));
            }
            _ => {}
        }
        at_start = false;
    }
    None
}

fn matching_close(toks: &[Tok], open: usize) -> Option<usize> {
    let mut depth = 0;
    for (i, t) in toks.iter().enumerate().skip(open) {
        match t.kind {
            TokKind::Open => depth += 1,
            TokKind::Close => {
                depth -= 1;
                if depth == 0 {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_nested_fields_and_indices() {
        let src = "(\n  version: 1,\n  grid: (\n    size_m: (10, 10),\n  ),\n  objects: [\n    Ground((optics: \"soil\")),\n    Tree((\n      position_m: (1, 2),\n      crown: (radius_x_m: -1),\n    )),\n  ],\n  optics: {\n    \"leaf\": BiLambertian(reflectance: [0.1]),\n  },\n)";
        assert_eq!(locate(src, "grid.size_m"), Some((4, 5)));
        assert_eq!(locate(src, "objects[1].crown.radius_x_m"), Some((10, 15)));
        assert_eq!(locate(src, "optics[\"leaf\"].reflectance"), Some((14, 26)));
        assert_eq!(locate(src, "objects[0].optics"), Some((7, 13)));
    }

    #[test]
    fn finds_duplicate_map_keys() {
        let src = "(\n  name: \"optics\",\n  optics: {\n    \"a\": L(x: [1]),\n    \"b\": L(x: {\"a\": 1}),\n    \"a\": L(x: [2]),\n  },\n)";
        assert_eq!(
            duplicate_key(src, "optics"),
            Some(("a".to_string(), (4, 5), (6, 5)))
        );
        let ok = "(\n  optics: {\n    \"a\": L(x: [1]),\n    \"b\": L(),\n  },\n)";
        assert_eq!(duplicate_key(ok, "optics"), None);
    }
}
