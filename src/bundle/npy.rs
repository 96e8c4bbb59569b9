//! Reading `.npy` files that may be hostile: the header is parsed here (a strict parser
//! for the one dictionary NumPy writes, no general Python-literal parser that a deeply
//! nested header could drive into a stack overflow), and everything it declares is
//! checked against the file before a byte of data is allocated:
//!
//! - the file is a regular file (after following links), not `/dev/zero` or a FIFO;
//! - the header is at most [`MAX_HEADER_BYTES`] long (the limit NumPy itself applies to
//!   untrusted files) and lies inside the file;
//! - the dtype is a plain little-endian number of the expected kind, the shape the one
//!   the caller expects (when it knows it), and the element count does not overflow;
//! - the file holds exactly `header + elements x itemsize` bytes: a header claiming
//!   10^12 elements in a 200-byte file is refused before anything is allocated, and so
//!   are truncated files and files with trailing bytes.
//!
//! The data are then read in blocks of about 1 MiB, converted from little-endian bytes
//! into the destination vector and handed, block by block, to the caller's check while
//! still in cache: one pass over the file, no second copy of the array.
//!
//! Every error is one line (header content is quoted with `{:?}`, so control characters
//! in a malicious header cannot break it) and carries no path: callers name the file.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// The longest header accepted, in bytes (NumPy's `max_header_size` default).
pub const MAX_HEADER_BYTES: usize = 10_000;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Why a `.npy` file cannot be read: one line, without the path (callers name the
/// file).
#[derive(Debug, thiserror::Error)]
pub enum NpyError {
    #[error("cannot read: {0}")]
    Read(std::io::Error),
    #[error("is a directory, not a .npy file")]
    Directory,
    #[error("is not a regular file (a device, FIFO or socket)")]
    NotRegular,
    /// The file opened is not a regular file (a link changed after the check).
    #[error("is not a regular file")]
    OpenedNotRegular,
    #[error("truncated: {size} bytes is too short for a .npy header")]
    Truncated { size: u64 },
    #[error("not a .npy file (no NumPy magic string)")]
    NoMagic,
    #[error(".npy format version {major}.{minor} is not supported")]
    Version { major: u8, minor: u8 },
    #[error("header length {len} bytes is above the limit of {max}", max = MAX_HEADER_BYTES)]
    HeaderTooLong { len: u64 },
    #[error("truncated: the header claims {len} bytes, the file holds {size} bytes")]
    HeaderBeyondFile { len: u64, size: u64 },
    #[error("header does not end with a newline")]
    NoNewline,
    #[error("header is not text")]
    HeaderNotText,
    #[error("malformed header: {0}")]
    Malformed(HeaderSyntax),
    #[error("header has no {}", describe_key(.0))]
    MissingKey(&'static str),
    #[error("dtype {0:?} is not a plain numeric type")]
    NotNumeric(String),
    #[error("shape {0:?} has more elements than memory can address")]
    TooManyElements(Vec<usize>),
    #[error(
        "truncated: shape {shape:?} of {dtype:?} needs {want} bytes of data, the file holds {have}"
    )]
    DataTruncated {
        shape: Vec<usize>,
        dtype: String,
        want: u128,
        have: u128,
    },
    #[error("{extra} bytes after the data of shape {shape:?} ({dtype:?}): not one .npy array")]
    TrailingBytes {
        extra: u128,
        shape: Vec<usize>,
        dtype: String,
    },
    /// [`NpyHeader::expect`]: a dtype other than the caller's.
    #[error("dtype {found:?} is not the expected {expected:?} ({})", describe_dtype(.expected))]
    UnexpectedDtype {
        found: String,
        expected: &'static str,
    },
    /// [`NpyHeader::expect`]: a shape other than the caller's.
    #[error("shape {found:?} does not match the expected {expected:?}")]
    UnexpectedShape {
        found: Vec<usize>,
        expected: Vec<usize>,
    },
    /// A read as another type than the header declares.
    #[error("dtype {found:?} is not {read:?}")]
    ReadAs { found: String, read: &'static str },
    #[error("truncated while reading the data: {0}")]
    DataUnreadable(std::io::Error),
    /// A value the caller's check refused: the element (e.g. "voxel (y 1, x 2, t 3,
    /// c 1)") and the check's reason (e.g. "is NaN").
    #[error("{element} {why}")]
    BadValue { element: String, why: String },
    /// Data that do not fill the header's shape (not expected after the checks).
    #[error("{0}")]
    Layout(ndarray::ShapeError),
}

/// Why a header's dictionary does not parse (byte offsets into the dictionary).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum HeaderSyntax {
    #[error("key {0:?} twice")]
    KeyTwice(String),
    #[error("unknown key {0:?}")]
    UnknownKey(String),
    #[error("unexpected text after the dictionary at byte {0}")]
    TrailingText(usize),
    #[error("expected {want:?} at byte {at}, found {}", describe_found(.found))]
    Expected {
        want: char,
        at: usize,
        found: Option<char>,
    },
    #[error("expected a quoted string at byte {at}, found {}", describe_found(.found))]
    ExpectedString { at: usize, found: Option<char> },
    #[error("unterminated string")]
    UnterminatedString,
    #[error("unexpected string at byte {0}")]
    UnexpectedString(usize),
    #[error("expected True or False at byte {at}, found {}", describe_found(.found))]
    ExpectedBool { at: usize, found: Option<char> },
    #[error("expected a dimension at byte {at}, found {}", describe_found(.found))]
    ExpectedDimension { at: usize, found: Option<char> },
    #[error("dimension {0} is too large")]
    DimensionTooLarge(String),
    #[error("more than 32 dimensions")]
    TooManyDimensions,
}

/// "'descr' (dtype)", "'shape'": a header key as messages name it.
fn describe_key(key: &str) -> String {
    match key {
        "descr" => "'descr' (dtype)".into(),
        _ => format!("'{key}'"),
    }
}

/// The character found where something else was expected, as messages show it.
fn describe_found(c: &Option<char>) -> String {
    match c {
        Some(c) => format!("{c:?}"),
        None => "the end".into(),
    }
}

/// An element type a bundle or report array may hold.
pub trait Element: Copy + Send + Sync + 'static {
    /// The NumPy descriptor of its little-endian form, e.g. `"<f8"`.
    const DTYPE: &'static str;
    /// Bytes per element.
    const SIZE: usize;
    fn from_le(bytes: &[u8]) -> Self;
    /// Exact conversion, for checks and messages.
    fn to_f64(self) -> f64;
}

impl Element for f64 {
    const DTYPE: &'static str = "<f8";
    const SIZE: usize = 8;
    #[inline]
    fn from_le(b: &[u8]) -> Self {
        f64::from_le_bytes(b.try_into().expect("8 bytes"))
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

impl Element for f32 {
    const DTYPE: &'static str = "<f4";
    const SIZE: usize = 4;
    #[inline]
    fn from_le(b: &[u8]) -> Self {
        f32::from_le_bytes(b.try_into().expect("4 bytes"))
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl Element for u32 {
    const DTYPE: &'static str = "<u4";
    const SIZE: usize = 4;
    #[inline]
    fn from_le(b: &[u8]) -> Self {
        u32::from_le_bytes(b.try_into().expect("4 bytes"))
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

/// What a `.npy` header declares, checked against the file's size.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyHeader {
    /// The NumPy descriptor, e.g. `"<f8"`.
    pub dtype: String,
    /// Bytes per element (from the descriptor).
    pub itemsize: usize,
    pub fortran_order: bool,
    pub shape: Vec<usize>,
    /// The number of elements (the shape's product, known not to overflow).
    pub len: usize,
    /// Where the data start.
    pub data_offset: u64,
}

impl NpyHeader {
    /// Refuses any dtype but `T`'s, and any shape but `shape` (when given).
    pub fn expect<T: Element>(&self, shape: Option<&[usize]>) -> Result<(), NpyError> {
        if self.dtype != T::DTYPE {
            return Err(NpyError::UnexpectedDtype {
                found: self.dtype.clone(),
                expected: T::DTYPE,
            });
        }
        if let Some(s) = shape {
            if self.shape != s {
                return Err(NpyError::UnexpectedShape {
                    found: self.shape.clone(),
                    expected: s.to_vec(),
                });
            }
        }
        Ok(())
    }
}

fn describe_dtype(d: &str) -> &'static str {
    match d {
        "<f8" => "f64, little-endian",
        "<f4" => "f32, little-endian",
        "<u4" => "u32, little-endian",
        _ => "another type",
    }
}

/// An open `.npy` file whose header has been read and checked against its size.
pub struct NpyFile {
    file: File,
    pub header: NpyHeader,
}

/// Opens `path` and checks its header (see the module docs).
pub fn open(path: &Path) -> Result<NpyFile, NpyError> {
    let meta = std::fs::metadata(path).map_err(NpyError::Read)?;
    if !meta.is_file() {
        return Err(if meta.is_dir() {
            NpyError::Directory
        } else {
            NpyError::NotRegular
        });
    }
    let mut file = File::open(path).map_err(NpyError::Read)?;
    // The size of the file actually opened (a link could have changed meanwhile).
    let size = file.metadata().map_err(NpyError::Read)?.len();
    if !file.metadata().map(|m| m.is_file()).unwrap_or(false) {
        return Err(NpyError::OpenedNotRegular);
    }
    let header = read_header(&mut file, size)?;
    Ok(NpyFile { file, header })
}

fn read_header(file: &mut File, size: u64) -> Result<NpyHeader, NpyError> {
    let truncated = || NpyError::Truncated { size };
    let mut pre = [0u8; 8];
    file.read_exact(&mut pre).map_err(|_| truncated())?;
    if &pre[..6] != MAGIC {
        return Err(NpyError::NoMagic);
    }
    let (major, minor) = (pre[6], pre[7]);
    let header_len = match (major, minor) {
        (1, 0) => {
            let mut b = [0u8; 2];
            file.read_exact(&mut b).map_err(|_| truncated())?;
            u16::from_le_bytes(b) as u64
        }
        (2, 0) | (3, 0) => {
            let mut b = [0u8; 4];
            file.read_exact(&mut b).map_err(|_| truncated())?;
            u32::from_le_bytes(b) as u64
        }
        _ => return Err(NpyError::Version { major, minor }),
    };
    let prefix = if major == 1 { 10 } else { 12 };
    if header_len > MAX_HEADER_BYTES as u64 {
        return Err(NpyError::HeaderTooLong { len: header_len });
    }
    if prefix + header_len > size {
        return Err(NpyError::HeaderBeyondFile {
            len: header_len,
            size,
        });
    }
    let mut text = vec![0u8; header_len as usize];
    file.read_exact(&mut text).map_err(|_| truncated())?;
    let text = match text.split_last() {
        Some((b'\n', rest)) => rest,
        _ => return Err(NpyError::NoNewline),
    };
    let text = std::str::from_utf8(text).map_err(|_| NpyError::HeaderNotText)?;
    let dict = parse_dict(text).map_err(NpyError::Malformed)?;
    let dtype = dict.descr.ok_or(NpyError::MissingKey("descr"))?;
    let fortran_order = dict
        .fortran_order
        .ok_or(NpyError::MissingKey("fortran_order"))?;
    let shape = dict.shape.ok_or(NpyError::MissingKey("shape"))?;
    let itemsize = itemsize(&dtype)?;
    let len = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| NpyError::TooManyElements(shape.clone()))?;
    let data_offset = prefix + header_len;
    let want = (len as u128) * (itemsize as u128);
    let have = (size - data_offset) as u128;
    if have != want {
        return Err(if have < want {
            NpyError::DataTruncated {
                shape,
                dtype,
                want,
                have,
            }
        } else {
            NpyError::TrailingBytes {
                extra: have - want,
                shape,
                dtype,
            }
        });
    }
    Ok(NpyHeader {
        dtype,
        itemsize,
        fortran_order,
        shape,
        len,
        data_offset,
    })
}

/// Bytes per element of a plain numeric descriptor such as `"<f8"`, `"|u1"`.
fn itemsize(dtype: &str) -> Result<usize, NpyError> {
    let bad = || NpyError::NotNumeric(dtype.to_string());
    let mut chars = dtype.chars();
    let order = chars.next().ok_or_else(bad)?;
    let kind = chars.next().ok_or_else(bad)?;
    let digits = chars.as_str();
    if !matches!(order, '<' | '>' | '|' | '=')
        || !matches!(kind, 'f' | 'i' | 'u' | 'b' | 'c')
        || digits.is_empty()
        || digits.len() > 2
        || !digits.bytes().all(|b| b.is_ascii_digit())
    {
        return Err(bad());
    }
    match digits.parse::<usize>() {
        Ok(n @ (1 | 2 | 4 | 8 | 16)) => Ok(n),
        _ => Err(bad()),
    }
}

#[derive(Default)]
struct Dict {
    descr: Option<String>,
    fortran_order: Option<bool>,
    shape: Option<Vec<usize>>,
}

/// Parses NumPy's header dictionary, e.g.
/// `{'descr': '<f8', 'fortran_order': False, 'shape': (8, 8, 10, 3), }` (any key
/// order, either quote, optional trailing commas, padding spaces). Nothing else.
fn parse_dict(text: &str) -> Result<Dict, HeaderSyntax> {
    let mut p = Parser {
        s: text.as_bytes(),
        i: 0,
    };
    let mut d = Dict::default();
    p.ws();
    p.expect(b'{')?;
    loop {
        p.ws();
        if p.eat(b'}') {
            break;
        }
        let key = p.string()?;
        p.ws();
        p.expect(b':')?;
        p.ws();
        match key.as_str() {
            "descr" if d.descr.is_none() => d.descr = Some(p.string()?),
            "fortran_order" if d.fortran_order.is_none() => d.fortran_order = Some(p.boolean()?),
            "shape" if d.shape.is_none() => d.shape = Some(p.tuple()?),
            "descr" | "fortran_order" | "shape" => return Err(HeaderSyntax::KeyTwice(key)),
            _ => return Err(HeaderSyntax::UnknownKey(key)),
        }
        p.ws();
        if !p.eat(b',') {
            p.ws();
            p.expect(b'}')?;
            break;
        }
    }
    p.ws();
    if p.i != p.s.len() {
        return Err(HeaderSyntax::TrailingText(p.i));
    }
    Ok(d)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
}

impl Parser<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && matches!(self.s[self.i], b' ' | b'\t') {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> bool {
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn found(&self) -> Option<char> {
        self.s.get(self.i).map(|&c| c as char)
    }

    fn expect(&mut self, c: u8) -> Result<(), HeaderSyntax> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(HeaderSyntax::Expected {
                want: c as char,
                at: self.i,
                found: self.found(),
            })
        }
    }

    fn string(&mut self) -> Result<String, HeaderSyntax> {
        let q = match self.s.get(self.i) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => {
                return Err(HeaderSyntax::ExpectedString {
                    at: self.i,
                    found: self.found(),
                })
            }
        };
        let start = self.i + 1;
        let len = self.s[start..]
            .iter()
            .position(|&c| c == q)
            .ok_or(HeaderSyntax::UnterminatedString)?;
        let v = &self.s[start..start + len];
        if v.len() > 64 || v.iter().any(|&c| c == b'\\' || !(b' '..=b'~').contains(&c)) {
            return Err(HeaderSyntax::UnexpectedString(self.i));
        }
        self.i = start + len + 1;
        Ok(String::from_utf8_lossy(v).into_owned())
    }

    fn boolean(&mut self) -> Result<bool, HeaderSyntax> {
        for (word, v) in [(&b"True"[..], true), (&b"False"[..], false)] {
            if self.s[self.i..].starts_with(word) {
                self.i += word.len();
                return Ok(v);
            }
        }
        Err(HeaderSyntax::ExpectedBool {
            at: self.i,
            found: self.found(),
        })
    }

    fn tuple(&mut self) -> Result<Vec<usize>, HeaderSyntax> {
        self.expect(b'(')?;
        let mut v = Vec::new();
        loop {
            self.ws();
            if self.eat(b')') {
                return Ok(v);
            }
            let start = self.i;
            while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                self.i += 1;
            }
            if self.i == start {
                return Err(HeaderSyntax::ExpectedDimension {
                    at: self.i,
                    found: self.found(),
                });
            }
            let digits = std::str::from_utf8(&self.s[start..self.i]).expect("ASCII digits");
            let d: usize = digits
                .parse()
                .map_err(|_| HeaderSyntax::DimensionTooLarge(digits.to_string()))?;
            self.eat(b'L'); // Python 2 long literals
            v.push(d);
            if v.len() > 32 {
                return Err(HeaderSyntax::TooManyDimensions);
            }
            self.ws();
            if !self.eat(b',') {
                self.ws();
                self.expect(b')')?;
                return Ok(v);
            }
        }
    }
}

/// Multi-index of the `flat`-th element of a C-order array of `shape`.
pub fn unravel(mut flat: usize, shape: &[usize]) -> Vec<usize> {
    let mut idx = vec![0; shape.len()];
    for (i, &d) in shape.iter().enumerate().rev() {
        if d > 0 {
            idx[i] = flat % d;
            flat /= d;
        }
    }
    idx
}

/// "(y 3, x 5, t 17, c 1)" from axis names and an index.
pub fn describe_index(axes: &[&str], idx: &[usize]) -> String {
    let parts: Vec<String> = idx
        .iter()
        .enumerate()
        .map(|(i, v)| match axes.get(i) {
            Some(a) if axes.len() == idx.len() => format!("{a} {v}"),
            _ => v.to_string(),
        })
        .collect();
    format!("({})", parts.join(", "))
}

/// Block size for reading: a multiple of 12 (of every channel count C: 1, 3, 4), so
/// that blocks of (H, W, T, C) sums start at a voxel's first channel.
pub const BLOCK_ELEMS: usize = 3 << 15;
const _: () = assert!(BLOCK_ELEMS.is_multiple_of(12));

/// The outcome of a block check: the C-order flat index and reason of the first bad
/// value.
pub type Bad = Option<(usize, String)>;

impl NpyFile {
    /// Reads the data as `T` (which the header must declare, see [`NpyHeader::expect`])
    /// in C order. `check(start, block)` sees each block of values (C-order flat index
    /// of its first element, a multiple of 3) right after it is decoded, and the first
    /// bad value it reports ends the read with that error, naming the element by its
    /// index on `axes`. Fortran-order files are transposed first and checked whole.
    pub fn read<T: Element>(
        self,
        mut check: impl FnMut(usize, &[T]) -> Bad,
        axes: &[&str],
    ) -> Result<Vec<T>, NpyError> {
        let shape = self.header.shape.clone();
        let mut out: Vec<T> = Vec::with_capacity(self.header.len);
        let fortran = self.fortran();
        self.blocks::<T>(|done, bytes| {
            out.extend(bytes.chunks_exact(T::SIZE).map(T::from_le));
            match fortran {
                true => None,
                false => check(done, &out[done..]),
            }
        })
        .map_err(|e| e.describe(axes, &shape))?;
        if fortran {
            out = to_c_order(out, &shape)?;
            if let Some(b) = check(0, &out) {
                return Err(Failure::Bad(b).describe(axes, &shape));
            }
        }
        Ok(out)
    }

    /// [`NpyFile::read`], each value mapped to `O` as it is read (the source array is
    /// never held whole, except for Fortran-order files).
    pub fn read_mapped<T: Element, O: Copy>(
        self,
        map: impl Fn(T) -> O,
        mut check: impl FnMut(usize, &[T]) -> Bad,
        axes: &[&str],
    ) -> Result<Vec<O>, NpyError> {
        if self.fortran() {
            let v = self.read(check, axes)?;
            return Ok(v.into_iter().map(map).collect());
        }
        let shape = self.header.shape.clone();
        let mut out: Vec<O> = Vec::with_capacity(self.header.len);
        let mut block: Vec<T> = Vec::with_capacity(BLOCK_ELEMS);
        self.blocks::<T>(|done, bytes| {
            block.clear();
            block.extend(bytes.chunks_exact(T::SIZE).map(T::from_le));
            let bad = check(done, &block);
            out.extend(block.iter().map(|&v| map(v)));
            bad
        })
        .map_err(|e| e.describe(axes, &shape))?;
        Ok(out)
    }

    fn fortran(&self) -> bool {
        self.header.fortran_order && self.header.shape.len() > 1
    }

    /// Elements per index of the first axis: one image row of a (H, W, ...) array.
    pub fn row_len(&self) -> usize {
        self.header.shape.iter().skip(1).product()
    }

    /// Reads rows `rows` of the first axis as `T` (which the header must declare) into
    /// `out` (cleared first; its capacity is reused), in C order, checking the values
    /// as [`NpyFile::read`] does: `check(start, block)` sees each block with `start`
    /// counted from the first element of the first row read (so a check can index
    /// per-row data of the same rows), and an error names the first bad element by its
    /// index in the whole array. Reads at offsets (the file is not consumed), so a
    /// caller keeps the file open and reads band after band. Fortran-order files are
    /// gathered run by run (one contiguous run of the first axis per element of a row)
    /// and checked whole: correct in the same memory, slow for large arrays (tstat
    /// never writes them).
    pub fn read_rows<T: Element>(
        &self,
        rows: std::ops::Range<usize>,
        out: &mut Vec<T>,
        mut check: impl FnMut(usize, &[T]) -> Bad,
        axes: &[&str],
    ) -> Result<(), NpyError> {
        use std::os::unix::fs::FileExt;
        let h = &self.header;
        if h.dtype != T::DTYPE {
            return Err(NpyError::ReadAs {
                found: h.dtype.clone(),
                read: T::DTYPE,
            });
        }
        let rows_total = h.shape.first().copied().unwrap_or(1);
        assert!(
            rows.start <= rows.end && rows.end <= rows_total,
            "rows {rows:?} of an array of {rows_total}"
        );
        let row_len = self.row_len();
        let first = rows.start * row_len;
        let len = (rows.end - rows.start) * row_len;
        let fail = |e: Failure| e.describe(axes, &h.shape);
        let io = |e: std::io::Error| Failure::Io(NpyError::DataUnreadable(e));
        out.clear();
        out.reserve(len);
        if !self.fortran() {
            let mut bytes = vec![0u8; BLOCK_ELEMS.min(len) * T::SIZE];
            let mut done = 0;
            while done < len {
                let n = BLOCK_ELEMS.min(len - done);
                let buf = &mut bytes[..n * T::SIZE];
                let at = h.data_offset + ((first + done) * T::SIZE) as u64;
                self.file.read_exact_at(buf, at).map_err(|e| fail(io(e)))?;
                out.extend(buf.chunks_exact(T::SIZE).map(T::from_le));
                if let Some((i, why)) = check(done, &out[done..]) {
                    return Err(fail(Failure::Bad((first + i, why))));
                }
                done += n;
            }
            return Ok(());
        }
        // Fortran order: element (i, j) (i on the first axis, j the C-order index
        // within a row) lies at i + d0 * f(j), f(j) the Fortran-order index of j's
        // multi-index over the other axes. Gather each j's run over `rows`, then
        // transpose into C order.
        let (d0, rest) = (rows_total, &h.shape[1..]);
        let n = rows.end - rows.start;
        let mut runs: Vec<T> = Vec::with_capacity(len);
        let mut bytes = vec![0u8; n * T::SIZE];
        for j in 0..row_len {
            let f = unravel(j, rest)
                .iter()
                .zip(rest)
                .rev()
                .fold(0usize, |acc, (&i, &d)| acc * d + i);
            let at = h.data_offset + ((rows.start + d0 * f) * T::SIZE) as u64;
            self.file
                .read_exact_at(&mut bytes, at)
                .map_err(|e| fail(io(e)))?;
            runs.extend(bytes.chunks_exact(T::SIZE).map(T::from_le));
        }
        out.extend((0..len).map(|k| runs[(k % row_len) * n + k / row_len]));
        drop(runs);
        match check(0, out) {
            Some((i, why)) => Err(fail(Failure::Bad((first + i, why)))),
            None => Ok(()),
        }
    }

    /// Feeds the data to `f` in blocks of raw bytes, with the element index of each
    /// block's start.
    fn blocks<T: Element>(mut self, mut f: impl FnMut(usize, &[u8]) -> Bad) -> Result<(), Failure> {
        use std::io::{Seek, SeekFrom};
        let h = &self.header;
        if h.dtype != T::DTYPE {
            return Err(Failure::Io(NpyError::ReadAs {
                found: h.dtype.clone(),
                read: T::DTYPE,
            }));
        }
        let len = h.len;
        self.file
            .seek(SeekFrom::Start(h.data_offset))
            .map_err(|e| Failure::Io(NpyError::Read(e)))?;
        let mut bytes = vec![0u8; BLOCK_ELEMS.min(len) * T::SIZE];
        let mut done = 0;
        while done < len {
            let n = BLOCK_ELEMS.min(len - done);
            let buf = &mut bytes[..n * T::SIZE];
            self.file
                .read_exact(buf)
                .map_err(|e| Failure::Io(NpyError::DataUnreadable(e)))?;
            if let Some(b) = f(done, buf) {
                return Err(Failure::Bad(b));
            }
            done += n;
        }
        Ok(())
    }
}

enum Failure {
    Io(NpyError),
    Bad((usize, String)),
}

impl Failure {
    fn describe(self, axes: &[&str], shape: &[usize]) -> NpyError {
        match self {
            Failure::Io(e) => e,
            Failure::Bad((flat, why)) => NpyError::BadValue {
                element: describe_voxel(axes, &unravel(flat, shape)),
                why,
            },
        }
    }
}

/// A Fortran-order array (first axis fastest) in C order.
fn to_c_order<T: Element>(v: Vec<T>, shape: &[usize]) -> Result<Vec<T>, NpyError> {
    let a = ndarray::ArrayD::from_shape_vec(ndarray::ShapeBuilder::f(ndarray::IxDyn(shape)), v)
        .map_err(NpyError::Layout)?;
    Ok(a.as_standard_layout().iter().copied().collect())
}

fn describe_voxel(axes: &[&str], idx: &[usize]) -> String {
    let what = if axes.len() == idx.len() && axes.first() == Some(&"y") {
        if axes.contains(&"t") {
            "voxel"
        } else {
            "pixel"
        }
    } else {
        "element"
    };
    format!("{what} {}", describe_index(axes, idx))
}

/// The first value of `block` (C-order flat index `start`) that fails `ok`, with its
/// reason from `why`.
#[inline]
pub fn first_bad<T: Element>(
    start: usize,
    block: &[T],
    ok: impl Fn(usize, T) -> bool,
    why: impl Fn(usize, T) -> String,
) -> Option<(usize, String)> {
    // Branch-light scan first; the position is looked for only when something fails.
    let all_ok = block
        .iter()
        .enumerate()
        .fold(true, |acc, (i, &v)| acc & ok(start + i, v));
    if all_ok {
        return None;
    }
    block
        .iter()
        .enumerate()
        .find(|&(i, &v)| !ok(start + i, v))
        .map(|(i, &v)| (start + i, why(start + i, v)))
}

/// "NaN", "+inf", "-2.5", "1e300" for messages (exponent notation for very large
/// and very small magnitudes, so that a message stays short).
pub fn show(v: f64) -> String {
    if v.is_nan() {
        "NaN".into()
    } else if v.is_infinite() {
        if v > 0.0 { "+inf" } else { "-inf" }.into()
    } else if v != 0.0 && !(1e-6..1e16).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy_bytes(dict: &str, data: &[u8], major: u8) -> Vec<u8> {
        let mut h = dict.as_bytes().to_vec();
        h.push(b'\n');
        let mut v = MAGIC.to_vec();
        v.extend([major, 0]);
        if major == 1 {
            v.extend((h.len() as u16).to_le_bytes());
        } else {
            v.extend((h.len() as u32).to_le_bytes());
        }
        v.extend(h);
        v.extend(data);
        v
    }

    fn open_bytes(bytes: &[u8]) -> Result<NpyFile, NpyError> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        std::fs::write(&p, bytes).unwrap();
        open(&p)
    }

    fn f64s(v: &[f64]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    fn one_line(e: &str) {
        assert!(!e.contains('\n') && !e.is_empty(), "{e:?}");
    }

    #[test]
    fn reads_what_ndarray_npy_and_numpy_write() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.npy");
        let a = ndarray::Array3::from_shape_fn((2, 3, 4), |(i, j, k)| (i * 12 + j * 4 + k) as f64);
        ndarray_npy::write_npy(&p, &a).unwrap();
        let f = open(&p).unwrap();
        assert_eq!(f.header.shape, vec![2, 3, 4]);
        f.header.expect::<f64>(Some(&[2, 3, 4])).unwrap();
        let v = f.read::<f64>(|_, _| None, &[]).unwrap();
        assert_eq!(v, a.iter().copied().collect::<Vec<_>>());
        // NumPy's own spelling: double quotes, version 2, 1-D "(6,)", Python 2 longs.
        let b = npy_bytes(
            "{\"descr\": \"<f8\", \"fortran_order\": False, \"shape\": (6L,), }   ",
            &f64s(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            2,
        );
        let f = open_bytes(&b).unwrap();
        assert_eq!(f.header.shape, vec![6]);
        // Fortran order: the file lists the first axis fastest.
        let b = npy_bytes(
            "{'shape': (2, 3), 'fortran_order': True, 'descr': '<f8'}",
            &f64s(&[0.0, 3.0, 1.0, 4.0, 2.0, 5.0]),
            1,
        );
        let v = open_bytes(&b)
            .unwrap()
            .read_mapped::<f64, f32>(|x| x as f32, |_, _| None, &[])
            .unwrap();
        assert_eq!(v, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    }

    #[test]
    fn hostile_headers_are_one_line_errors_before_any_allocation() {
        let good = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }";
        let data = f64s(&[1.0; 4]);
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (b"".to_vec(), "truncated"),
            (b"\x93NUMP".to_vec(), "truncated"),
            (b"PK\x03\x04 this is a zip".to_vec(), "magic"),
            (npy_bytes(good, &data, 7), "version 7.0"),
            (
                // 10^12 elements declared in a tiny file.
                npy_bytes(
                    "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000), }",
                    &data,
                    1,
                ),
                "truncated",
            ),
            (
                npy_bytes(
                    "{'descr': '<f8', 'fortran_order': False, 'shape': (4294967296, 4294967296, 4294967296), }",
                    &data,
                    1,
                ),
                "more elements than memory",
            ),
            (
                npy_bytes(
                    "{'descr': '<f8', 'fortran_order': False, 'shape': (99999999999999999999999,), }",
                    &data,
                    1,
                ),
                "too large",
            ),
            (npy_bytes(good, &data[..20], 1), "truncated"),
            (npy_bytes(good, &f64s(&[1.0; 5]), 1), "8 bytes after the data"),
            (
                npy_bytes(&"(".repeat(5000), &data, 1),
                "malformed header",
            ),
            (
                npy_bytes(&format!("{{'descr': {}", "[".repeat(9000)), &data, 2),
                "malformed header",
            ),
            (npy_bytes("{'descr': [('a', '<f8')], 'fortran_order': False, 'shape': (2,)}", &data, 1), "quoted string"),
            (npy_bytes("{'descr': '|O', 'fortran_order': False, 'shape': (2, 2)}", &data, 1), "not a plain numeric"),
            (npy_bytes("{'descr': '<f8', 'fortran_order': 0, 'shape': (2, 2)}", &data, 1), "True or False"),
            (npy_bytes("{'descr': '<f8', 'shape': (2, 2)}", &data, 1), "fortran_order"),
            (npy_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), 'x': 1}", &data, 1), "unknown key"),
            (npy_bytes("{'descr': '<f8', 'descr': '<f8', 'fortran_order': False, 'shape': (2, 2)}", &data, 1), "twice"),
            (npy_bytes("{'descr': '<f8\n\x07', 'fortran_order': False, 'shape': (2, 2)}", &data, 1), "malformed"),
            (npy_bytes("{'descr': '<f8', 'fortran_order': False, 'shape': (-2, 2)}", &data, 1), "dimension"),
        ];
        for (bytes, want) in &cases {
            let e = open_bytes(bytes)
                .err()
                .unwrap_or_else(|| panic!("accepted for {want}"))
                .to_string();
            one_line(&e);
            assert!(e.contains(want), "expected {want:?} in {e:?}");
        }
        // A header length field far beyond the file (v2: 4 GiB).
        let mut b = MAGIC.to_vec();
        b.extend([2, 0]);
        b.extend(u32::MAX.to_le_bytes());
        b.extend(b"{}");
        let e = open_bytes(&b).err().unwrap().to_string();
        assert!(e.contains("above the limit"), "{e}");
        // Header bytes that are not text, and one without its final newline.
        let mut b = npy_bytes(good, &data, 1);
        b[20] = 0xff;
        one_line(&open_bytes(&b).err().unwrap().to_string());
        let mut b = MAGIC.to_vec();
        b.extend([1, 0, 4, 0]);
        b.extend(b"{}  ");
        assert!(open_bytes(&b)
            .err()
            .unwrap()
            .to_string()
            .contains("newline"));
    }

    #[test]
    fn wrong_dtype_or_shape_is_named() {
        let b = npy_bytes(
            "{'descr': '<f4', 'fortran_order': False, 'shape': (4,)}",
            &[0u8; 16],
            1,
        );
        let f = open_bytes(&b).unwrap();
        let e = f.header.expect::<f64>(Some(&[4])).unwrap_err().to_string();
        assert!(e.contains("\"<f4\"") && e.contains("f64"), "{e}");
        f.header.expect::<f32>(Some(&[4])).unwrap();
        let e = f
            .header
            .expect::<f32>(Some(&[2, 2]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("[4]") && e.contains("[2, 2]"), "{e}");
        let e = f.read::<f64>(|_, _| None, &[]).unwrap_err().to_string();
        one_line(&e);
    }

    #[test]
    fn row_ranges_read_what_a_whole_read_holds_in_either_order() {
        let dir = tempfile::tempdir().unwrap();
        let (c, f) = (dir.path().join("c.npy"), dir.path().join("f.npy"));
        let a = ndarray::Array4::from_shape_fn((7, 3, 4, 3), |(y, x, t, c)| {
            (((y * 3 + x) * 4 + t) * 3 + c) as f64 * 0.5
        });
        ndarray_npy::write_npy(&c, &a).unwrap();
        let mut fa = ndarray::Array4::<f64>::zeros(ndarray::ShapeBuilder::f(a.raw_dim()));
        fa.assign(&a);
        ndarray_npy::write_npy(&f, &fa).unwrap();
        let whole: Vec<f64> = a.iter().copied().collect();
        let row = 3 * 4 * 3;
        for path in [&c, &f] {
            let file = open(path).unwrap();
            assert_eq!(file.row_len(), row);
            let mut out = Vec::new();
            for (y0, y1) in [(0, 7), (0, 1), (2, 5), (6, 7), (3, 3)] {
                let mut starts = Vec::new();
                file.read_rows::<f64>(
                    y0..y1,
                    &mut out,
                    |s, b| {
                        starts.push((s, b.len()));
                        None
                    },
                    &[],
                )
                .unwrap();
                assert_eq!(out, whole[y0 * row..y1 * row], "{path:?} rows {y0}..{y1}");
                // The check sees every value once, counted from the first row read.
                let seen: usize = starts.iter().map(|&(_, n)| n).sum();
                assert_eq!(seen, (y1 - y0) * row);
                assert!(starts.iter().all(|&(s, _)| s % 3 == 0 && s < seen.max(1)));
            }
        }
        // A bad value is named by its place in the whole array.
        let axes = ["y", "x", "t", "c"];
        for path in [&c, &f] {
            let file = open(path).unwrap();
            let check = |s: usize, b: &[f64]| {
                first_bad(s, b, |i, _| i != row + 5, |_, x| format!("is {}", show(x)))
            };
            let e = file
                .read_rows::<f64>(4..6, &mut Vec::new(), check, &axes)
                .unwrap_err()
                .to_string();
            assert_eq!(e, "voxel (y 5, x 0, t 1, c 2) is 92.5", "{path:?}");
        }
        // A wrong type is refused, not reinterpreted.
        let e = open(&c)
            .unwrap()
            .read_rows::<f32>(0..1, &mut Vec::new(), |_, _| None, &[])
            .unwrap_err()
            .to_string();
        one_line(&e);
    }

    #[test]
    fn the_first_bad_value_is_named_by_its_index() {
        let mut v = vec![1.0f64; 2 * 3 * 4 * 3];
        // Shape (2, 3, 4, 3): (y 1, x 2, t 3, c 1) is flat index ((1 * 3 + 2) * 4 + 3) * 3 + 1.
        let at = |y: usize, x: usize, t: usize, c: usize| ((y * 3 + x) * 4 + t) * 3 + c;
        v[at(1, 2, 3, 1)] = f64::NAN;
        v[at(1, 2, 3, 2)] = -1.0;
        let b = npy_bytes(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3, 4, 3), }",
            &f64s(&v),
            1,
        );
        let check = |s: usize, b: &[f64]| {
            first_bad(s, b, |_, x| x >= 0.0, |_, x| format!("is {}", show(x)))
        };
        let e = open_bytes(&b)
            .unwrap()
            .read::<f64>(check, &["y", "x", "t", "c"])
            .unwrap_err()
            .to_string();
        assert_eq!(e, "voxel (y 1, x 2, t 3, c 1) is NaN");
        assert_eq!(unravel(5, &[2, 3]), vec![1, 2]);
        assert_eq!(describe_index(&["y", "x"], &[1, 2]), "(y 1, x 2)");
        assert_eq!(show(f64::NEG_INFINITY), "-inf");
        assert_eq!(show(1e300), "1e300");
        assert_eq!(show(-2.5e-9), "-2.5e-9");
        assert_eq!(show(0.001), "0.001");
    }
}
