//! pbrt-v4's tokenizer (pbrt-v4 `parser.cpp`, "Tokenizer"): `#` comments to the end of the line,
//! double-quoted strings with C escapes, `[` and `]`, and bare words (directive names, numbers,
//! `true`/`false`) separated by whitespace, quotes or brackets.

/// What a token is; quoted strings keep their quotes off and their escapes decoded.
#[derive(Clone, Debug, PartialEq)]
pub enum TokenKind {
    /// A double-quoted string, escapes decoded.
    Str(String),
    /// A bare word: a directive name, a number or `true`/`false`.
    Word(String),
    Open,
    Close,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    pub kind: TokenKind,
    /// 1-based line of the token's first character.
    pub line: u32,
}

/// Most tokens one file may hold. Each costs ~70 bytes here, so this bounds the memory a hostile
/// file of one-character numbers can make the tokenizer use (~7 GB); real scenes keep large
/// meshes in PLY files and stay far below it.
pub const MAX_TOKENS: usize = 100_000_000;

/// Tokens between two charges to the load's memory budget (and checks of its cancel flag).
const CHARGE_EVERY: usize = 1 << 16;

/// What a token's text costs in memory: its heap block (the allocator's chunks are 16-byte
/// multiples of at least 32 bytes, with 8 bytes of header). The token itself lives in the
/// token array, charged by its capacity. A file of one-character numbers costs ~50 times its
/// size.
fn token_bytes(t: &Token) -> u64 {
    match &t.kind {
        TokenKind::Str(s) | TokenKind::Word(s) => {
            (s.capacity() as u64 + 8).next_multiple_of(16).max(32)
        }
        TokenKind::Open | TokenKind::Close => 0,
    }
}

/// Splits `text` into tokens. Errors name the line (the caller adds the file). The tokens'
/// memory is reserved from the load's budget as they are made ([`crate::limits`]) and returned
/// with the reservation, which the caller holds while it uses them.
pub fn tokenize(text: &str) -> Result<(Vec<Token>, crate::limits::Reservation), (u32, String)> {
    // A UTF-8 byte-order mark is not a token (editors on Windows write one).
    let b = text.strip_prefix('\u{feff}').unwrap_or(text).as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    let mut line: u32 = 1;
    let mut held = crate::limits::reserve(0, String::new).map_err(|e| (line, e.to_string()))?;
    let mut charged = 0;
    // The token array's own buffers: each growth allocates the new one while the old is still
    // held, so every capacity reached is charged (about twice the final buffer, its peak).
    let mut charged_capacity = 0;
    let array = |cap: usize| (cap * std::mem::size_of::<Token>()) as u64;
    while i < b.len() {
        if out.len() >= charged + CHARGE_EVERY {
            let grown = out.capacity().max(charged_capacity);
            let bytes: u64 = out[charged..].iter().map(token_bytes).sum::<u64>()
                + if grown > charged_capacity {
                    array(grown)
                } else {
                    0
                };
            charged_capacity = grown;
            held.grow(bytes, || {
                format!("the {} tokens read up to line {line}", out.len())
            })
            .map_err(|e| (line, e.to_string()))?;
            charged = out.len();
        }
        if out.len() >= MAX_TOKENS {
            return Err((
                line,
                format!(
                    "more than {MAX_TOKENS} tokens in one file (split it with Include, or move meshes to PLY files)"
                ),
            ));
        }
        let c = b[i];
        match c {
            b'\n' => {
                line = line.saturating_add(1);
                i += 1;
            }
            b' ' | b'\t' | b'\r' | 0x0b | 0x0c => i += 1,
            b'#' => {
                while i < b.len() && b[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' => {
                out.push(Token {
                    kind: TokenKind::Open,
                    line,
                });
                i += 1;
            }
            b']' => {
                out.push(Token {
                    kind: TokenKind::Close,
                    line,
                });
                i += 1;
            }
            b'"' => {
                let start_line = line;
                i += 1;
                let mut s: Vec<u8> = Vec::new();
                loop {
                    let Some(&ch) = b.get(i) else {
                        return Err((start_line, "unterminated string".into()));
                    };
                    match ch {
                        b'"' => {
                            i += 1;
                            break;
                        }
                        b'\n' => {
                            return Err((start_line, "new line inside a quoted string".into()));
                        }
                        b'\\' => {
                            let Some(&e) = b.get(i + 1) else {
                                return Err((start_line, "unterminated string".into()));
                            };
                            s.push(match e {
                                b'b' => 8,
                                b'f' => 12,
                                b'n' => b'\n',
                                b'r' => b'\r',
                                b't' => b'\t',
                                b'\\' => b'\\',
                                b'\'' => b'\'',
                                b'"' => b'"',
                                other => {
                                    return Err((
                                        line,
                                        format!(
                                            "unknown escape sequence '\\{}' in a string",
                                            char::from(other).escape_default()
                                        ),
                                    ));
                                }
                            });
                            i += 2;
                        }
                        _ => {
                            s.push(ch);
                            i += 1;
                        }
                    }
                }
                // The input is UTF-8 and escapes only produce ASCII, so this cannot fail; lossy
                // keeps it panic-free regardless.
                out.push(Token {
                    kind: TokenKind::Str(String::from_utf8_lossy(&s).into_owned()),
                    line: start_line,
                });
            }
            _ => {
                let start = i;
                while i < b.len()
                    && !matches!(
                        b[i],
                        b' ' | b'\t' | b'\r' | b'\n' | 0x0b | 0x0c | b'"' | b'[' | b']' | b'#'
                    )
                {
                    i += 1;
                }
                out.push(Token {
                    kind: TokenKind::Word(String::from_utf8_lossy(&b[start..i]).into_owned()),
                    line,
                });
            }
        }
    }
    let grown = out.capacity().saturating_sub(charged_capacity);
    let bytes: u64 = out[charged..].iter().map(token_bytes).sum::<u64>() + array(grown);
    held.grow(bytes, || format!("the {} tokens of the file", out.len()))
        .map_err(|e| (line, e.to_string()))?;
    Ok((out, held))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &str) -> Vec<TokenKind> {
        tokenize(s).unwrap().0.into_iter().map(|t| t.kind).collect()
    }

    #[test]
    fn tokens_comments_strings_and_brackets() {
        use TokenKind::*;
        assert_eq!(
            kinds("Shape \"sphere\" # comment \"x\"\n \"float radius\" [2.5e1]"),
            vec![
                Word("Shape".into()),
                Str("sphere".into()),
                Str("float radius".into()),
                Open,
                Word("2.5e1".into()),
                Close
            ]
        );
        assert_eq!(kinds(r#""a\"b\\c\n""#), vec![Str("a\"b\\c\n".into())]);
        let (t, _) = tokenize("A\n\nB").unwrap();
        assert_eq!((t[0].line, t[1].line), (1, 3));
    }

    /// A byte-order mark before the first directive is skipped, not an unknown directive.
    #[test]
    fn a_byte_order_mark_is_skipped() {
        assert_eq!(
            kinds("\u{feff}WorldBegin"),
            vec![TokenKind::Word("WorldBegin".into())]
        );
    }

    /// The tokens' memory counts against the budget: 200k one-digit numbers (~400 KB of
    /// text) need more than a 4 MiB budget holds.
    #[test]
    fn tokens_are_charged_to_the_budget() {
        let text = "1 ".repeat(200_000);
        let ctx = crate::limits::LoadContext::new(crate::limits::Budget::new(4 << 20), None);
        let e = crate::limits::scope(ctx.clone(), || tokenize(&text).map(|_| ())).unwrap_err();
        assert!(
            e.1.contains("tokens") && e.1.contains("memory budget"),
            "{e:?}"
        );
        assert_eq!(ctx.budget.used(), 0, "a refused load holds nothing");
        let (t, held) = crate::limits::scope(ctx.clone(), || tokenize("1 2 3")).unwrap();
        assert_eq!(t.len(), 3);
        assert!(ctx.budget.used() > 0);
        drop(held);
        assert_eq!(ctx.budget.used(), 0);
    }

    #[test]
    fn unterminated_string_names_its_line() {
        assert_eq!(tokenize("A\n\"abc").unwrap_err().0, 2);
        assert!(tokenize("\"abc\\").is_err());
        assert!(tokenize("\"a\\q\"").is_err());
    }
}
