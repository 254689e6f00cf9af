//! The binary FBX 7.x node format, read by hand.
//!
//! A file is the 27-byte header (`Kaydara FBX Binary  \0`, `0x1A 0x00`, a little-endian u32
//! version) followed by a list of node records closed by a null record. A node record is
//! `end_offset, num_properties, property_list_len` (u32 each, u64 from version 7500 on), a
//! one-byte name length and the name, the properties, then nested records closed by a null
//! record. Properties are typed by a one-letter code: scalars `Y C I F D L`, strings `S`, raw
//! bytes `R`, and arrays `f d l i b` which may be zlib-compressed.
//!
//! Every length and offset is checked against the bytes that are actually there, arrays are
//! bounded before anything is allocated (a zlib stream cannot expand more than ~1032:1), and
//! nesting is limited, so a truncated or hostile file is an error, never a panic or an
//! out-of-memory abort.

use std::io::Read;

pub const MAGIC: &[u8; 21] = b"Kaydara FBX Binary  \0";
const HEADER_LEN: usize = 27;
const MAX_DEPTH: usize = 64;
/// Deflate's maximum expansion ratio is 1032:1; anything claiming more is corrupt.
const MAX_INFLATE_RATIO: u64 = 1032;

/// A parse error with the byte offset where it was found.
#[derive(Debug, thiserror::Error)]
#[error("at byte {offset}: {message}")]
pub struct ParseError {
    pub offset: usize,
    pub message: String,
}

/// One typed property value of a node.
#[derive(Clone, Debug, PartialEq)]
pub enum Property {
    Bool(bool),
    I16(i16),
    I32(i32),
    I64(i64),
    F32(f32),
    F64(f64),
    String(String),
    Raw(Vec<u8>),
    BoolArray(Vec<bool>),
    I32Array(Vec<i32>),
    I64Array(Vec<i64>),
    F32Array(Vec<f32>),
    F64Array(Vec<f64>),
}

impl Property {
    /// A scalar number as f64 (bools are 0/1).
    pub fn as_f64(&self) -> Option<f64> {
        Some(match *self {
            Property::Bool(b) => b as u8 as f64,
            Property::I16(v) => v as f64,
            Property::I32(v) => v as f64,
            Property::I64(v) => v as f64,
            Property::F32(v) => v as f64,
            Property::F64(v) => v,
            _ => return None,
        })
    }

    /// A scalar integer (floats are not accepted: ids and indices must be exact).
    pub fn as_i64(&self) -> Option<i64> {
        Some(match *self {
            Property::Bool(b) => b as i64,
            Property::I16(v) => v as i64,
            Property::I32(v) => v as i64,
            Property::I64(v) => v,
            _ => return None,
        })
    }

    pub fn as_str(&self) -> Option<&str> {
        match self {
            Property::String(s) => Some(s),
            _ => None,
        }
    }

    /// A numeric array as f64 values.
    pub fn to_f64_vec(&self) -> Option<Vec<f64>> {
        Some(match self {
            Property::F64Array(v) => v.clone(),
            Property::F32Array(v) => v.iter().map(|&x| x as f64).collect(),
            Property::I32Array(v) => v.iter().map(|&x| x as f64).collect(),
            Property::I64Array(v) => v.iter().map(|&x| x as f64).collect(),
            _ => return None,
        })
    }

    /// An integer array as i64 values.
    pub fn to_i64_vec(&self) -> Option<Vec<i64>> {
        Some(match self {
            Property::I32Array(v) => v.iter().map(|&x| x as i64).collect(),
            Property::I64Array(v) => v.clone(),
            _ => return None,
        })
    }
}

/// A node record: a name, its properties and nested nodes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Node {
    pub name: String,
    pub props: Vec<Property>,
    pub children: Vec<Node>,
}

impl Node {
    pub fn child(&self, name: &str) -> Option<&Node> {
        self.children.iter().find(|c| c.name == name)
    }

    pub fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Node> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    pub fn prop(&self, i: usize) -> Option<&Property> {
        self.props.get(i)
    }

    /// The first property of the child `name`, as a string.
    pub fn child_str(&self, name: &str) -> Option<&str> {
        self.child(name)?.prop(0)?.as_str()
    }
}

/// A parsed file: its version and top-level nodes.
#[derive(Clone, Debug, Default)]
pub struct Document {
    pub version: u32,
    pub nodes: Vec<Node>,
}

impl Document {
    pub fn node(&self, name: &str) -> Option<&Node> {
        self.nodes.iter().find(|n| n.name == name)
    }
}

/// True if the bytes start like a text (ASCII) FBX file.
pub fn looks_like_ascii_fbx(data: &[u8]) -> bool {
    let head = &data[..data.len().min(4096)];
    let text = String::from_utf8_lossy(head);
    text.trim_start_matches('\u{feff}')
        .trim_start()
        .starts_with("; FBX")
        || text.contains("FBXHeaderExtension:")
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    /// 64-bit record header fields (version ≥ 7500).
    wide: bool,
}

impl<'a> Reader<'a> {
    fn err<T>(&self, message: impl Into<String>) -> Result<T, ParseError> {
        Err(ParseError {
            offset: self.pos,
            message: message.into(),
        })
    }

    fn bytes(&mut self, n: usize) -> Result<&'a [u8], ParseError> {
        let end = match self.pos.checked_add(n) {
            Some(e) if e <= self.data.len() => e,
            _ => {
                return self.err(format!(
                    "the file is truncated: {n} more bytes were expected, {} remain",
                    self.data.len().saturating_sub(self.pos)
                ));
            }
        };
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], ParseError> {
        let s = self.bytes(N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    fn u8(&mut self) -> Result<u8, ParseError> {
        Ok(self.array::<1>()?[0])
    }

    fn u32(&mut self) -> Result<u32, ParseError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A record header field: u32, or u64 in 7.5+ files.
    fn field(&mut self) -> Result<u64, ParseError> {
        if self.wide {
            Ok(u64::from_le_bytes(self.array()?))
        } else {
            Ok(self.u32()? as u64)
        }
    }

    /// Reads one node record, or `None` for a null record. `limit` is the end of the enclosing
    /// record (or of the file).
    fn node(&mut self, depth: usize, limit: usize) -> Result<Option<Node>, ParseError> {
        if depth > MAX_DEPTH {
            return self.err(format!(
                "nodes are nested more than {MAX_DEPTH} levels deep"
            ));
        }
        let start = self.pos;
        let end = self.field()?;
        let num_props = self.field()?;
        let props_len = self.field()?;
        let name_len = self.u8()? as usize;
        if end == 0 && num_props == 0 && props_len == 0 && name_len == 0 {
            return Ok(None);
        }
        let name = String::from_utf8_lossy(self.bytes(name_len)?).into_owned();
        let end = usize::try_from(end).unwrap_or(usize::MAX);
        if end <= start || end > limit {
            self.pos = start;
            return self.err(format!(
                "node '{name}' claims to end at byte {end}, outside its enclosing record (bytes {start}..{limit}); the file is truncated or corrupt"
            ));
        }
        let props_end = usize::try_from(props_len)
            .ok()
            .and_then(|l| self.pos.checked_add(l))
            .filter(|&e| e <= end);
        let Some(props_end) = props_end else {
            return self.err(format!(
                "node '{name}': its property list ({props_len} bytes) overruns the node"
            ));
        };
        // Every property takes at least one byte, which bounds the count before allocating.
        if num_props > props_len {
            return self.err(format!(
                "node '{name}' claims {num_props} properties in {props_len} bytes"
            ));
        }
        let mut props = Vec::with_capacity(num_props.min(64) as usize);
        for _ in 0..num_props {
            props.push(self.property(props_end, &name)?);
        }
        if self.pos != props_end {
            return self.err(format!(
                "node '{name}': the properties end at byte {} but the record says {props_end}",
                self.pos
            ));
        }
        let mut children = Vec::new();
        while self.pos < end {
            match self.node(depth + 1, end)? {
                Some(n) => children.push(n),
                None => break,
            }
        }
        if self.pos != end {
            return self.err(format!(
                "node '{name}': its nested records end at byte {} but the record says {end}",
                self.pos
            ));
        }
        Ok(Some(Node {
            name,
            props,
            children,
        }))
    }

    fn property(&mut self, limit: usize, node: &str) -> Result<Property, ParseError> {
        let code = self.u8()?;
        let p = match code {
            b'Y' => Property::I16(i16::from_le_bytes(self.array()?)),
            b'C' => Property::Bool(self.u8()? != 0),
            b'I' => Property::I32(i32::from_le_bytes(self.array()?)),
            b'F' => Property::F32(f32::from_le_bytes(self.array()?)),
            b'D' => Property::F64(f64::from_le_bytes(self.array()?)),
            b'L' => Property::I64(i64::from_le_bytes(self.array()?)),
            b'S' | b'R' => {
                let len = self.u32()? as usize;
                let bytes = self.bytes(len)?;
                if code == b'S' {
                    Property::String(String::from_utf8_lossy(bytes).into_owned())
                } else {
                    Property::Raw(bytes.to_vec())
                }
            }
            b'f' | b'd' | b'l' | b'i' | b'b' => self.array_property(code, node)?,
            other => {
                self.pos -= 1;
                return self.err(format!(
                    "node '{node}': unknown property type code 0x{other:02x}"
                ));
            }
        };
        if self.pos > limit {
            return self.err(format!(
                "node '{node}': a property runs past the end of the property list"
            ));
        }
        Ok(p)
    }

    fn array_property(&mut self, code: u8, node: &str) -> Result<Property, ParseError> {
        let count = self.u32()? as u64;
        let encoding = self.u32()?;
        let stored_len = self.u32()? as usize;
        let at = self.pos;
        let stored = self.bytes(stored_len)?;
        let elem: u64 = match code {
            b'b' => 1,
            b'i' | b'f' => 4,
            _ => 8,
        };
        let raw_len = count * elem;
        let raw: std::borrow::Cow<[u8]> = match encoding {
            0 => {
                if raw_len != stored_len as u64 {
                    self.pos = at;
                    return self.err(format!(
                        "node '{node}': an array of {count} elements is stored in {stored_len} bytes"
                    ));
                }
                std::borrow::Cow::Borrowed(stored)
            }
            1 => {
                if raw_len > (stored_len as u64 + 64) * MAX_INFLATE_RATIO {
                    self.pos = at;
                    return self.err(format!(
                        "node '{node}': a compressed array claims {count} elements from only {stored_len} bytes"
                    ));
                }
                // Within the ratio is not enough (2.4 MB of zlib can claim 2.4 GB): the
                // array and the values it becomes are charged to the load's budget first.
                if let Err(e) = crate::limits::charge(raw_len.saturating_mul(2), || {
                    format!("node '{node}': a compressed array of {count} elements")
                }) {
                    self.pos = at;
                    return self.err(e.to_string());
                }
                let mut out = Vec::with_capacity(raw_len as usize);
                let mut dec = flate2::read::ZlibDecoder::new(stored).take(raw_len + 1);
                if let Err(e) = dec.read_to_end(&mut out) {
                    self.pos = at;
                    return self.err(format!(
                        "node '{node}': a compressed array is corrupt ({e})"
                    ));
                }
                if out.len() as u64 != raw_len {
                    self.pos = at;
                    return self.err(format!(
                        "node '{node}': a compressed array holds {} bytes, {raw_len} were declared",
                        out.len()
                    ));
                }
                std::borrow::Cow::Owned(out)
            }
            other => {
                self.pos = at;
                return self.err(format!("node '{node}': unknown array encoding {other}"));
            }
        };
        Ok(match code {
            b'b' => Property::BoolArray(raw.iter().map(|&b| b != 0).collect()),
            b'i' => Property::I32Array(
                raw.chunks_exact(4)
                    .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect(),
            ),
            b'f' => Property::F32Array(
                raw.chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect(),
            ),
            b'l' => Property::I64Array(
                raw.chunks_exact(8)
                    .map(|c| i64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                    .collect(),
            ),
            _ => Property::F64Array(
                raw.chunks_exact(8)
                    .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                    .collect(),
            ),
        })
    }
}

/// Parses a binary FBX 7.x file.
pub fn parse(data: &[u8]) -> Result<Document, ParseError> {
    if data.len() < MAGIC.len() || &data[..MAGIC.len()] != MAGIC {
        let message = if looks_like_ascii_fbx(data) {
            "this is a text (ASCII) FBX file; only binary FBX 7.x is supported: re-export it as binary FBX"
        } else {
            "not a binary FBX file (it does not start with the 'Kaydara FBX Binary' signature)"
        };
        return Err(ParseError {
            offset: 0,
            message: message.into(),
        });
    }
    if data.len() < HEADER_LEN {
        return Err(ParseError {
            offset: data.len(),
            message: "the file is truncated inside its header".into(),
        });
    }
    let version = u32::from_le_bytes([data[23], data[24], data[25], data[26]]);
    if !(7000..8000).contains(&version) {
        return Err(ParseError {
            offset: 23,
            message: format!(
                "FBX version {}.{} is not supported (binary FBX 7.x only)",
                version / 1000,
                (version % 1000) / 100
            ),
        });
    }
    let mut r = Reader {
        data,
        pos: HEADER_LEN,
        wide: version >= 7500,
    };
    let mut nodes = Vec::new();
    loop {
        if r.pos >= data.len() {
            return r.err("the file is truncated: the list of top-level nodes is not closed");
        }
        match r.node(0, data.len())? {
            Some(n) => nodes.push(n),
            None => break,
        }
    }
    Ok(Document { version, nodes })
}
