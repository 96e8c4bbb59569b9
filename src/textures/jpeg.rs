//! JPEG decoding as libjpeg(-turbo) decodes with its default settings, which is how
//! Mitsuba 3 reads JPEG textures: the integer "slow" IDCT (`JDCT_ISLOW`, jidctint.c),
//! "fancy" triangular chroma upsampling (`do_fancy_upsampling`, jdsample.c) and the
//! fixed-point YCbCr -> RGB tables of jdcolor.c. Every step is integer arithmetic
//! written from libjpeg's formulas, so the texels are libjpeg's bit for bit (the
//! `image` crate's decoder rounds its IDCT and upsampler differently, which biased
//! 4:2:0 textures by up to 5/255).
//!
//! Read: baseline and extended sequential (SOF0/SOF1) and progressive (SOF2) Huffman
//! JPEGs of 8-bit precision, with any integral sampling factors, restart intervals,
//! 1 component (grey) or 3 (YCbCr, or RGB when an Adobe marker or the component ids
//! say so, as libjpeg guesses). Refused with one error each: 4 components (CMYK/YCCK,
//! which Mitsuba refuses too), 12-bit, lossless, hierarchical and arithmetic-coded
//! files. Not emulated: libjpeg's block smoothing of progressive files whose scans
//! stop before the last AC refinement (complete files are not smoothed).
//!
//! Hostile files end in a [`JpegError`], never a panic: every length is checked
//! against the bytes left, sizes against a texel limit before anything is allocated,
//! and allocations are fallible. Entropy data cut short decodes as zeros, as libjpeg
//! does (with a warning there).

/// Why a JPEG cannot be decoded; the message is a short reason without the path.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum JpegError {
    /// The file ends before a marker segment or the frame is complete.
    #[error("is a truncated JPEG ({0})")]
    Truncated(&'static str),
    /// A malformed marker segment or entropy-coded value.
    #[error("is a corrupt JPEG ({0})")]
    Corrupt(&'static str),
    /// A valid JPEG of a kind textures do not read.
    #[error("is a JPEG of an unsupported kind ({0})")]
    Unsupported(&'static str),
    /// Four colour components: CMYK or YCCK. Mitsuba refuses them ("Unsupported
    /// number of components").
    #[error("is a {0} JPEG (4 components; Mitsuba reads only grey and RGB JPEGs)")]
    FourComponents(&'static str),
    /// Over the texel limit given to [`decode`].
    #[error("is {width} x {height} pixels, above the limit of {limit} pixels")]
    TooLarge { width: u32, height: u32, limit: u64 },
    /// A buffer that cannot be allocated.
    #[error("needs {0} bytes of JPEG buffers, more than can be allocated")]
    Alloc(usize),
}

/// A decoded JPEG: 8-bit samples, rows from the top, 1 (grey) or 3 (RGB) channels
/// interleaved.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decoded {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: Vec<u8>,
}

/// Zigzag index -> natural (row-major) index, with 16 extra entries of 63 as libjpeg's
/// `jpeg_natural_order` has, so a corrupt run length past 63 lands on 63.
const NATURAL: [usize; 80] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63, 63, 63, 63, 63, 63, 63, 63, 63, 63, 63,
    63, 63, 63, 63, 63, 63,
];

fn vec_filled<T: Clone>(n: usize, v: T) -> Result<Vec<T>, JpegError> {
    let mut out = Vec::new();
    out.try_reserve_exact(n)
        .map_err(|_| JpegError::Alloc(n.saturating_mul(std::mem::size_of::<T>())))?;
    out.resize(n, v);
    Ok(out)
}

// ---------------------------------------------------------------------------------
// Huffman tables and the entropy-coded bit stream.

#[derive(Clone)]
struct Huffman {
    /// For the first 8 bits: (code length, value), length 0 when longer.
    fast: [(u8, u8); 256],
    /// Largest code of each length (-1 when none), as jdhuff.c's `maxcode`.
    maxcode: [i32; 18],
    /// Index into `values` of the first code of each length minus that code.
    valoffset: [i32; 17],
    values: Vec<u8>,
}

impl Huffman {
    /// Builds a table from DHT's counts per length (1..=16) and values, refusing what
    /// jdhuff.c refuses (more than 256 values, codes that overflow their length).
    fn new(counts: &[u8; 16], values: &[u8]) -> Result<Huffman, JpegError> {
        let total: usize = counts.iter().map(|&c| c as usize).sum();
        if total > 256 || total != values.len() {
            return Err(JpegError::Corrupt("bad Huffman table"));
        }
        let mut maxcode = [-1i32; 18];
        let mut valoffset = [0i32; 17];
        let mut fast = [(0u8, 0u8); 256];
        let mut code: i32 = 0;
        let mut k: usize = 0;
        for len in 1..=16usize {
            let n = counts[len - 1] as usize;
            if n > 0 {
                valoffset[len] = k as i32 - code;
                for _ in 0..n {
                    if len <= 8 {
                        let shift = 8 - len;
                        let first = (code as usize) << shift;
                        for e in fast.iter_mut().skip(first).take(1 << shift) {
                            *e = (len as u8, values[k]);
                        }
                    }
                    code += 1;
                    k += 1;
                }
                maxcode[len] = code - 1;
            }
            if code >= 1 << len {
                // jdhuff.c: codes of this length overflow (all-ones is reserved).
                if code > 1 << len {
                    return Err(JpegError::Corrupt("bad Huffman table"));
                }
            }
            code <<= 1;
        }
        maxcode[17] = i32::MAX; // a sentinel, as jdhuff.c's
        Ok(Huffman {
            fast,
            maxcode,
            valoffset,
            values: values.to_vec(),
        })
    }
}

/// Reads entropy-coded bits, unstuffing 0xFF00; at a marker it stops and supplies
/// zeros, as libjpeg does.
struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    acc: u64,
    nbits: u32,
    /// Set when a marker (other than stuffing) was reached; `pos` points at its 0xFF.
    at_marker: bool,
}

impl<'a> Bits<'a> {
    fn new(data: &'a [u8], pos: usize) -> Self {
        Bits {
            data,
            pos,
            acc: 0,
            nbits: 0,
            at_marker: false,
        }
    }

    fn fill(&mut self) {
        while self.nbits <= 56 {
            let mut byte = 0u8;
            if !self.at_marker && self.pos < self.data.len() {
                let b = self.data[self.pos];
                if b == 0xFF {
                    // Skip fill bytes 0xFF 0xFF ...; 0xFF 0x00 is a data 0xFF.
                    let mut p = self.pos + 1;
                    while p < self.data.len() && self.data[p] == 0xFF {
                        p += 1;
                    }
                    if p < self.data.len() && self.data[p] == 0 {
                        byte = 0xFF;
                        self.pos = p + 1;
                    } else {
                        self.at_marker = true;
                    }
                } else {
                    byte = b;
                    self.pos += 1;
                }
            }
            self.acc |= (byte as u64) << (56 - self.nbits);
            self.nbits += 8;
        }
    }

    fn bits(&mut self, n: u32) -> u32 {
        if n == 0 {
            return 0;
        }
        if self.nbits < n {
            self.fill();
        }
        let v = (self.acc >> (64 - n)) as u32;
        self.acc <<= n;
        self.nbits -= n;
        v
    }

    fn bit(&mut self) -> bool {
        self.bits(1) == 1
    }

    /// One Huffman symbol; a code longer than 16 bits decodes as 0 (libjpeg warns
    /// JWRN_HUFF_BAD_CODE and goes on with 0).
    fn decode(&mut self, h: &Huffman) -> u8 {
        if self.nbits < 16 {
            self.fill();
        }
        let peek = (self.acc >> 56) as usize;
        let (len, val) = h.fast[peek];
        if len > 0 {
            self.acc <<= len;
            self.nbits -= len as u32;
            return val;
        }
        let mut code = (self.acc >> 56) as i32;
        self.acc <<= 8;
        self.nbits -= 8;
        let mut len = 8;
        loop {
            if len > 16 {
                return 0;
            }
            if code <= h.maxcode[len] {
                let idx = code + h.valoffset[len];
                return h.values.get(idx as usize).copied().unwrap_or(0);
            }
            code = (code << 1) | self.bits(1) as i32;
            len += 1;
        }
    }

    /// `s` bits read and sign-extended (HUFF_EXTEND); `s` is 0..=16.
    fn receive_extend(&mut self, s: u32) -> i32 {
        if s == 0 {
            return 0;
        }
        let v = self.bits(s) as i32;
        if v < 1 << (s - 1) {
            v - (1 << s) + 1
        } else {
            v
        }
    }

    /// At a restart: drop the bits left, and the RSTn marker if it is next (a missing
    /// or misplaced one is passed over, as libjpeg's resync does for the common cases).
    fn restart(&mut self) {
        self.acc = 0;
        self.nbits = 0;
        let mut p = self.pos;
        // Find the next marker.
        while p + 1 < self.data.len() && !(self.data[p] == 0xFF && self.data[p + 1] != 0) {
            p += 1;
        }
        while p + 1 < self.data.len() && self.data[p + 1] == 0xFF {
            p += 1;
        }
        if p + 1 < self.data.len() && (0xD0..=0xD7).contains(&self.data[p + 1]) {
            self.pos = p + 2;
        } else {
            self.pos = p.min(self.data.len());
        }
        self.at_marker = false;
    }
}

// ---------------------------------------------------------------------------------
// The frame.

struct Component {
    id: u8,
    h: usize,
    v: usize,
    tq: usize,
    /// Blocks covering the component (jpeg_component_info.width_in_blocks ...).
    bw: usize,
    bh: usize,
    /// Blocks stored: whole MCUs.
    pbw: usize,
    pbh: usize,
    /// Samples of the component (downsampled_width/height).
    dw: usize,
    dh: usize,
    /// Quantized coefficients, natural order, 64 per block.
    coefs: Vec<i16>,
    dc_tbl: usize,
    ac_tbl: usize,
    dc_pred: i32,
}

struct Frame {
    width: usize,
    height: usize,
    progressive: bool,
    comps: Vec<Component>,
    hmax: usize,
    vmax: usize,
    mcux: usize,
    mcuy: usize,
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn u8(&mut self, what: &'static str) -> Result<u8, JpegError> {
        let b = *self.data.get(self.pos).ok_or(JpegError::Truncated(what))?;
        self.pos += 1;
        Ok(b)
    }
    fn u16(&mut self, what: &'static str) -> Result<u16, JpegError> {
        Ok(u16::from_be_bytes([self.u8(what)?, self.u8(what)?]))
    }
    /// The next marker code, skipping fill bytes (and, as libjpeg does with a warning,
    /// any garbage before it).
    fn marker(&mut self) -> Result<u8, JpegError> {
        loop {
            let b = self.u8("no end-of-image marker")?;
            if b != 0xFF {
                continue;
            }
            let mut m = self.u8("no end-of-image marker")?;
            while m == 0xFF {
                m = self.u8("no end-of-image marker")?;
            }
            if m != 0 {
                return Ok(m);
            }
        }
    }
    /// A marker segment's payload (after its length field).
    fn segment(&mut self, what: &'static str) -> Result<&'a [u8], JpegError> {
        let len = self.u16(what)? as usize;
        if len < 2 {
            return Err(JpegError::Corrupt("marker segment length below 2"));
        }
        let end = self.pos + len - 2;
        if end > self.data.len() {
            return Err(JpegError::Truncated(what));
        }
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }
}

fn sof_kind(m: u8) -> Option<Result<bool, JpegError>> {
    match m {
        0xC0 | 0xC1 => Some(Ok(false)),
        0xC2 => Some(Ok(true)),
        0xC3 => Some(Err(JpegError::Unsupported("lossless"))),
        0xC5..=0xC7 => Some(Err(JpegError::Unsupported("hierarchical"))),
        0xC9..=0xCB | 0xCD..=0xCF => Some(Err(JpegError::Unsupported("arithmetic-coded"))),
        _ => None,
    }
}

/// The width and height a JPEG's frame header declares, read without decoding.
pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32), JpegError> {
    let mut r = Reader {
        data: bytes,
        pos: 0,
    };
    if r.u8("no start-of-image marker")? != 0xFF || r.u8("no start-of-image marker")? != 0xD8 {
        return Err(JpegError::Corrupt("no start-of-image marker"));
    }
    loop {
        let m = r.marker()?;
        match m {
            0xD8 | 0x01 | 0xD0..=0xD7 => continue,
            0xD9 => return Err(JpegError::Corrupt("end of image before a frame header")),
            0xDA => return Err(JpegError::Corrupt("scan before a frame header")),
            _ => {}
        }
        let seg = r.segment("marker segment")?;
        if let Some(kind) = sof_kind(m) {
            kind?;
            if seg.len() < 5 {
                return Err(JpegError::Truncated("frame header"));
            }
            let h = u16::from_be_bytes([seg[1], seg[2]]) as u32;
            let w = u16::from_be_bytes([seg[3], seg[4]]) as u32;
            return Ok((w, h));
        }
    }
}

/// Decodes a JPEG as libjpeg does by default. `max_texels`: the largest
/// width x height accepted, checked before anything is allocated.
pub fn decode(bytes: &[u8], max_texels: u64) -> Result<Decoded, JpegError> {
    let mut r = Reader {
        data: bytes,
        pos: 0,
    };
    if r.u8("no start-of-image marker")? != 0xFF || r.u8("no start-of-image marker")? != 0xD8 {
        return Err(JpegError::Corrupt("no start-of-image marker"));
    }
    let mut qt: [Option<[u16; 64]>; 4] = [None; 4];
    let mut dc_tables: [Option<Huffman>; 4] = [None, None, None, None];
    let mut ac_tables: [Option<Huffman>; 4] = [None, None, None, None];
    let mut restart_interval = 0usize;
    let mut frame: Option<Frame> = None;
    let mut saw_jfif = false;
    let mut adobe_transform: Option<u8> = None;
    let mut scans = 0usize;
    loop {
        let m = match r.marker() {
            Ok(m) => m,
            // A file that ends after at least one scan: what was decoded stands, as
            // libjpeg's (warning "premature end of data").
            Err(JpegError::Truncated(_)) if scans > 0 => break,
            Err(e) => return Err(e),
        };
        match m {
            0xD9 => break,
            0xD8 | 0x01 | 0xD0..=0xD7 => continue,
            _ => {}
        }
        let seg = r.segment("marker segment")?;
        if let Some(kind) = sof_kind(m) {
            let progressive = kind?;
            if frame.is_some() {
                return Err(JpegError::Corrupt("two frame headers"));
            }
            frame = Some(parse_sof(seg, progressive, max_texels)?);
            continue;
        }
        match m {
            0xC4 => parse_dht(seg, &mut dc_tables, &mut ac_tables)?,
            0xDB => parse_dqt(seg, &mut qt)?,
            0xDD => {
                if seg.len() < 2 {
                    return Err(JpegError::Truncated("restart interval"));
                }
                restart_interval = u16::from_be_bytes([seg[0], seg[1]]) as usize;
            }
            // jdmarker.c examine_app0/examine_app14: JFIF needs 14 bytes, Adobe 12.
            0xE0 if seg.len() >= 14 && seg.starts_with(b"JFIF\0") => saw_jfif = true,
            0xEE if seg.len() >= 12 && seg.starts_with(b"Adobe") => adobe_transform = Some(seg[11]),
            0xDA => {
                let f = frame
                    .as_mut()
                    .ok_or(JpegError::Corrupt("scan before a frame header"))?;
                let end = decode_scan(
                    bytes,
                    r.pos,
                    seg,
                    f,
                    &dc_tables,
                    &ac_tables,
                    restart_interval,
                )?;
                r.pos = end;
                scans += 1;
                if scans > 1000 {
                    return Err(JpegError::Corrupt("more than 1000 scans"));
                }
            }
            0xDC => return Err(JpegError::Unsupported("DNL marker")),
            _ => {} // APPn, COM, ...: skipped
        }
    }
    let f = frame.ok_or(JpegError::Corrupt("no frame header"))?;
    if scans == 0 {
        return Err(JpegError::Corrupt("no scan"));
    }
    finish(f, &qt, saw_jfif, adobe_transform)
}

fn parse_sof(seg: &[u8], progressive: bool, max_texels: u64) -> Result<Frame, JpegError> {
    if seg.len() < 6 {
        return Err(JpegError::Truncated("frame header"));
    }
    if seg[0] != 8 {
        return Err(JpegError::Unsupported("not 8-bit precision"));
    }
    let height = u16::from_be_bytes([seg[1], seg[2]]) as usize;
    let width = u16::from_be_bytes([seg[3], seg[4]]) as usize;
    let n = seg[5] as usize;
    if width == 0 || height == 0 {
        return Err(JpegError::Unsupported("no pixels or a height given by DNL"));
    }
    if (width as u64) * (height as u64) > max_texels {
        return Err(JpegError::TooLarge {
            width: width as u32,
            height: height as u32,
            limit: max_texels,
        });
    }
    if n == 0 || n > 4 {
        return Err(JpegError::Corrupt("component count not 1 to 4"));
    }
    if seg.len() < 6 + 3 * n {
        return Err(JpegError::Truncated("frame header"));
    }
    let mut comps = Vec::with_capacity(n);
    for i in 0..n {
        let c = &seg[6 + 3 * i..9 + 3 * i];
        let (h, v) = ((c[1] >> 4) as usize, (c[1] & 15) as usize);
        if !(1..=4).contains(&h) || !(1..=4).contains(&v) {
            return Err(JpegError::Corrupt("sampling factor not 1 to 4"));
        }
        if c[2] > 3 {
            return Err(JpegError::Corrupt("quantization table number above 3"));
        }
        comps.push(Component {
            id: c[0],
            h,
            v,
            tq: c[2] as usize,
            bw: 0,
            bh: 0,
            pbw: 0,
            pbh: 0,
            dw: 0,
            dh: 0,
            coefs: Vec::new(),
            dc_tbl: 0,
            ac_tbl: 0,
            dc_pred: 0,
        });
    }
    let hmax = comps.iter().map(|c| c.h).max().unwrap_or(1);
    let vmax = comps.iter().map(|c| c.v).max().unwrap_or(1);
    for c in &comps {
        if hmax % c.h != 0 || vmax % c.v != 0 {
            return Err(JpegError::Unsupported("fractional sampling factors"));
        }
    }
    let mcux = width.div_ceil(8 * hmax);
    let mcuy = height.div_ceil(8 * vmax);
    for c in comps.iter_mut() {
        c.dw = (width * c.h).div_ceil(hmax);
        c.dh = (height * c.v).div_ceil(vmax);
        c.bw = c.dw.div_ceil(8);
        c.bh = c.dh.div_ceil(8);
        c.pbw = mcux * c.h;
        c.pbh = mcuy * c.v;
        c.coefs = vec_filled(c.pbw * c.pbh * 64, 0i16)?;
    }
    Ok(Frame {
        width,
        height,
        progressive,
        comps,
        hmax,
        vmax,
        mcux,
        mcuy,
    })
}

fn parse_dht(
    mut seg: &[u8],
    dc: &mut [Option<Huffman>; 4],
    ac: &mut [Option<Huffman>; 4],
) -> Result<(), JpegError> {
    while !seg.is_empty() {
        if seg.len() < 17 {
            return Err(JpegError::Truncated("Huffman table"));
        }
        let (class, id) = (seg[0] >> 4, (seg[0] & 15) as usize);
        if class > 1 || id > 3 {
            return Err(JpegError::Corrupt("bad Huffman table class or number"));
        }
        let mut counts = [0u8; 16];
        counts.copy_from_slice(&seg[1..17]);
        let total: usize = counts.iter().map(|&c| c as usize).sum();
        if seg.len() < 17 + total {
            return Err(JpegError::Truncated("Huffman table"));
        }
        let table = Huffman::new(&counts, &seg[17..17 + total])?;
        if class == 0 {
            dc[id] = Some(table);
        } else {
            ac[id] = Some(table);
        }
        seg = &seg[17 + total..];
    }
    Ok(())
}

fn parse_dqt(mut seg: &[u8], qt: &mut [Option<[u16; 64]>; 4]) -> Result<(), JpegError> {
    while !seg.is_empty() {
        let (prec, id) = (seg[0] >> 4, (seg[0] & 15) as usize);
        if prec > 1 || id > 3 {
            return Err(JpegError::Corrupt(
                "bad quantization table precision or number",
            ));
        }
        let size = if prec == 0 { 64 } else { 128 };
        if seg.len() < 1 + size {
            return Err(JpegError::Truncated("quantization table"));
        }
        let mut t = [0u16; 64];
        for k in 0..64 {
            t[NATURAL[k]] = if prec == 0 {
                seg[1 + k] as u16
            } else {
                u16::from_be_bytes([seg[1 + 2 * k], seg[2 + 2 * k]])
            };
        }
        qt[id] = Some(t);
        seg = &seg[1 + size..];
    }
    Ok(())
}

/// Decodes one scan whose entropy-coded data starts at `start`; returns where the
/// data ends (the next marker).
fn decode_scan(
    bytes: &[u8],
    start: usize,
    seg: &[u8],
    f: &mut Frame,
    dc_tables: &[Option<Huffman>; 4],
    ac_tables: &[Option<Huffman>; 4],
    restart_interval: usize,
) -> Result<usize, JpegError> {
    if seg.is_empty() {
        return Err(JpegError::Truncated("scan header"));
    }
    let ns = seg[0] as usize;
    if ns == 0 || ns > 4 || seg.len() < 4 + 2 * ns {
        return Err(JpegError::Corrupt("bad scan header"));
    }
    let mut idx = Vec::with_capacity(ns);
    for i in 0..ns {
        let (cid, tables) = (seg[1 + 2 * i], seg[2 + 2 * i]);
        let ci = f
            .comps
            .iter()
            .position(|c| c.id == cid)
            .ok_or(JpegError::Corrupt(
                "scan names a component not in the frame",
            ))?;
        if idx.contains(&ci) {
            return Err(JpegError::Corrupt("scan names a component twice"));
        }
        let (td, ta) = ((tables >> 4) as usize, (tables & 15) as usize);
        if td > 3 || ta > 3 {
            return Err(JpegError::Corrupt("bad Huffman table number"));
        }
        f.comps[ci].dc_tbl = td;
        f.comps[ci].ac_tbl = ta;
        f.comps[ci].dc_pred = 0;
        idx.push(ci);
    }
    let p = 1 + 2 * ns;
    let (ss, se, ah, al) = (
        seg[p] as usize,
        seg[p + 1] as usize,
        (seg[p + 2] >> 4) as u32,
        (seg[p + 2] & 15) as u32,
    );
    // What the scan does.
    #[derive(Clone, Copy, PartialEq)]
    enum Kind {
        Sequential,
        DcFirst,
        DcRefine,
        AcFirst,
        AcRefine,
    }
    let kind = if !f.progressive {
        Kind::Sequential
    } else {
        // jdphuff.c start_pass_phuff_decoder's checks.
        let bad = if ss == 0 {
            se != 0
        } else {
            se < ss || se > 63 || ns != 1
        } || (ah != 0 && al + 1 != ah)
            || al > 13;
        if bad {
            return Err(JpegError::Corrupt("bad progressive scan parameters"));
        }
        match (ss == 0, ah == 0) {
            (true, true) => Kind::DcFirst,
            (true, false) => Kind::DcRefine,
            (false, true) => Kind::AcFirst,
            (false, false) => Kind::AcRefine,
        }
    };
    // The tables the scan needs must have been defined.
    for &ci in &idx {
        let c = &f.comps[ci];
        let need_dc = matches!(kind, Kind::Sequential | Kind::DcFirst);
        let need_ac = matches!(kind, Kind::Sequential | Kind::AcFirst | Kind::AcRefine);
        if (need_dc && dc_tables[c.dc_tbl].is_none()) || (need_ac && ac_tables[c.ac_tbl].is_none())
        {
            return Err(JpegError::Corrupt("scan uses an undefined Huffman table"));
        }
    }
    let mut bits = Bits::new(bytes, start);
    let mut eobrun: u32 = 0;
    // Blocks of one MCU: (component index, block column, block row) per MCU origin.
    let (units_x, units_y, single) = if ns == 1 {
        let c = &f.comps[idx[0]];
        (c.bw, c.bh, true)
    } else {
        let blocks: usize = idx.iter().map(|&ci| f.comps[ci].h * f.comps[ci].v).sum();
        if blocks > 10 {
            return Err(JpegError::Corrupt("more than 10 blocks in an MCU"));
        }
        (f.mcux, f.mcuy, false)
    };
    let mut todo = restart_interval;
    let empty = Huffman {
        fast: [(0, 0); 256],
        maxcode: [-1; 18],
        valoffset: [0; 17],
        values: Vec::new(),
    };
    for my in 0..units_y {
        for mx in 0..units_x {
            if restart_interval > 0 {
                if todo == 0 {
                    bits.restart();
                    for &ci in &idx {
                        f.comps[ci].dc_pred = 0;
                    }
                    eobrun = 0;
                    todo = restart_interval;
                }
                todo -= 1;
            }
            for &ci in &idx {
                let c = &mut f.comps[ci];
                let (nh, nv) = if single { (1, 1) } else { (c.h, c.v) };
                let dc = dc_tables[c.dc_tbl].as_ref().unwrap_or(&empty);
                let ac = ac_tables[c.ac_tbl].as_ref().unwrap_or(&empty);
                for by in 0..nv {
                    for bx in 0..nh {
                        let (col, row) = (mx * nh + bx, my * nv + by);
                        let off = (row * c.pbw + col) * 64;
                        let block = &mut c.coefs[off..off + 64];
                        match kind {
                            Kind::Sequential => {
                                decode_sequential(&mut bits, dc, ac, &mut c.dc_pred, block)?
                            }
                            Kind::DcFirst => {
                                let s = bits.decode(dc) as u32;
                                if s > 16 {
                                    return Err(JpegError::Corrupt("DC difference too long"));
                                }
                                c.dc_pred = c.dc_pred.wrapping_add(bits.receive_extend(s));
                                block[0] = (c.dc_pred << al) as i16;
                            }
                            Kind::DcRefine => {
                                if bits.bit() {
                                    block[0] |= (1i32 << al) as i16;
                                }
                            }
                            Kind::AcFirst => {
                                ac_first(&mut bits, ac, &mut eobrun, ss, se, al, block)?
                            }
                            Kind::AcRefine => {
                                ac_refine(&mut bits, ac, &mut eobrun, ss, se, al, block)
                            }
                        }
                    }
                }
            }
        }
    }
    // The next marker: where the bit reader stopped, or the first one after.
    let mut p = bits.pos;
    while p + 1 < bytes.len() {
        if bytes[p] == 0xFF && bytes[p + 1] != 0 && !(0xD0..=0xD7).contains(&bytes[p + 1]) {
            break;
        }
        p += 1;
    }
    Ok(p.min(bytes.len()))
}

fn decode_sequential(
    bits: &mut Bits,
    dc: &Huffman,
    ac: &Huffman,
    pred: &mut i32,
    block: &mut [i16],
) -> Result<(), JpegError> {
    let s = bits.decode(dc) as u32;
    if s > 16 {
        return Err(JpegError::Corrupt("DC difference too long"));
    }
    *pred = pred.wrapping_add(bits.receive_extend(s));
    block[0] = *pred as i16;
    let mut k = 1;
    while k < 64 {
        let rs = bits.decode(ac);
        let (r, s) = ((rs >> 4) as usize, (rs & 15) as u32);
        if s != 0 {
            k += r;
            block[NATURAL[k.min(79)]] = bits.receive_extend(s) as i16;
        } else if r == 15 {
            k += 15;
        } else {
            break;
        }
        k += 1;
    }
    Ok(())
}

fn ac_first(
    bits: &mut Bits,
    ac: &Huffman,
    eobrun: &mut u32,
    ss: usize,
    se: usize,
    al: u32,
    block: &mut [i16],
) -> Result<(), JpegError> {
    if *eobrun > 0 {
        *eobrun -= 1;
        return Ok(());
    }
    let mut k = ss;
    while k <= se {
        let rs = bits.decode(ac);
        let (r, s) = ((rs >> 4) as usize, (rs & 15) as u32);
        if s != 0 {
            k += r;
            let v = bits.receive_extend(s);
            block[NATURAL[k.min(79)]] = (v << al) as i16;
        } else if r == 15 {
            k += 15;
        } else {
            let mut run = 1u32 << r;
            if r > 0 {
                run += bits.bits(r as u32);
            }
            *eobrun = run - 1;
            break;
        }
        k += 1;
    }
    Ok(())
}

/// jdphuff.c decode_mcu_AC_refine.
fn ac_refine(
    bits: &mut Bits,
    ac: &Huffman,
    eobrun: &mut u32,
    ss: usize,
    se: usize,
    al: u32,
    block: &mut [i16],
) {
    let p1: i16 = (1i32 << al) as i16;
    let m1: i16 = (-1i32 << al) as i16;
    let refine = |bits: &mut Bits, coef: &mut i16| {
        if bits.bit() && (*coef & p1) == 0 {
            *coef = if *coef >= 0 {
                coef.wrapping_add(p1)
            } else {
                coef.wrapping_add(m1)
            };
        }
    };
    let mut k = ss;
    if *eobrun == 0 {
        while k <= se {
            let rs = bits.decode(ac);
            let (mut r, s) = ((rs >> 4) as i32, rs & 15);
            let mut value = 0i16;
            if s != 0 {
                value = if bits.bit() { p1 } else { m1 };
            } else if r != 15 {
                *eobrun = 1 << r;
                if r > 0 {
                    *eobrun += bits.bits(r as u32);
                }
                break;
            }
            loop {
                let coef = &mut block[NATURAL[k.min(79)]];
                if *coef != 0 {
                    refine(bits, coef);
                } else {
                    r -= 1;
                    if r < 0 {
                        break;
                    }
                }
                k += 1;
                if k > se {
                    break;
                }
            }
            if value != 0 {
                block[NATURAL[k.min(79)]] = value;
            }
            k += 1;
        }
    }
    if *eobrun > 0 {
        while k <= se {
            let coef = &mut block[NATURAL[k]];
            if *coef != 0 {
                refine(bits, coef);
            }
            k += 1;
        }
        *eobrun -= 1;
    }
}

// ---------------------------------------------------------------------------------
// IDCT, upsampling, colour conversion.

/// libjpeg's post-IDCT range limit (jdmaster.c prepare_range_limit_table): the value
/// masked to 10 bits, then clamped (a wrapped value past +-512 maps as libjpeg's table).
#[inline]
fn idct_range_limit(x: i64) -> u8 {
    let j = (x & 1023) as i32;
    if j < 128 {
        (j + 128) as u8
    } else if j < 512 {
        255
    } else if j < 896 {
        0
    } else {
        (j - 896) as u8
    }
}

/// jidctint.c jpeg_idct_islow: dequantizes and inverse-transforms one block into
/// `out` (8 rows of `stride` samples).
pub fn idct_islow(coefs: &[i16], quant: &[u16; 64], out: &mut [u8], stride: usize) {
    const CONST_BITS: u32 = 13;
    const PASS1_BITS: u32 = 2;
    const F0_298: i64 = 2446;
    const F0_390: i64 = 3196;
    const F0_541: i64 = 4433;
    const F0_765: i64 = 6270;
    const F0_899: i64 = 7373;
    const F1_175: i64 = 9633;
    const F1_501: i64 = 12299;
    const F1_847: i64 = 15137;
    const F1_961: i64 = 16069;
    const F2_053: i64 = 16819;
    const F2_562: i64 = 20995;
    const F3_072: i64 = 25172;
    let descale = |x: i64, n: u32| (x + (1i64 << (n - 1))) >> n;
    let mut ws = [0i32; 64];
    for col in 0..8 {
        let deq = |row: usize| coefs[row * 8 + col] as i64 * quant[row * 8 + col] as i64;
        if (1..8).all(|row| coefs[row * 8 + col] == 0) {
            let dc = (deq(0) << PASS1_BITS) as i32;
            for row in 0..8 {
                ws[row * 8 + col] = dc;
            }
            continue;
        }
        let (z2, z3) = (deq(2), deq(6));
        let z1 = (z2 + z3) * F0_541;
        let tmp2 = z1 - z3 * F1_847;
        let tmp3 = z1 + z2 * F0_765;
        let (z2, z3) = (deq(0), deq(4));
        let tmp0 = (z2 + z3) << CONST_BITS;
        let tmp1 = (z2 - z3) << CONST_BITS;
        let (t10, t13, t11, t12) = (tmp0 + tmp3, tmp0 - tmp3, tmp1 + tmp2, tmp1 - tmp2);
        let (o0, o1, o2, o3) = odd(deq(7), deq(5), deq(3), deq(1));
        let n = CONST_BITS - PASS1_BITS;
        ws[col] = descale(t10 + o3, n) as i32;
        ws[7 * 8 + col] = descale(t10 - o3, n) as i32;
        ws[8 + col] = descale(t11 + o2, n) as i32;
        ws[6 * 8 + col] = descale(t11 - o2, n) as i32;
        ws[2 * 8 + col] = descale(t12 + o1, n) as i32;
        ws[5 * 8 + col] = descale(t12 - o1, n) as i32;
        ws[3 * 8 + col] = descale(t13 + o0, n) as i32;
        ws[4 * 8 + col] = descale(t13 - o0, n) as i32;
    }
    fn odd(t0: i64, t1: i64, t2: i64, t3: i64) -> (i64, i64, i64, i64) {
        let (z1, z2, z3, z4) = (t0 + t3, t1 + t2, t0 + t2, t1 + t3);
        let z5 = (z3 + z4) * F1_175;
        let (t0, t1, t2, t3) = (t0 * F0_298, t1 * F2_053, t2 * F3_072, t3 * F1_501);
        let (z1, z2, z3, z4) = (-z1 * F0_899, -z2 * F2_562, -z3 * F1_961, -z4 * F0_390);
        let (z3, z4) = (z3 + z5, z4 + z5);
        (t0 + z1 + z3, t1 + z2 + z4, t2 + z2 + z3, t3 + z1 + z4)
    }
    for row in 0..8 {
        let w = &ws[row * 8..row * 8 + 8];
        let o = &mut out[row * stride..row * stride + 8];
        if w[1..].iter().all(|&v| v == 0) {
            let v = idct_range_limit(descale(w[0] as i64, PASS1_BITS + 3));
            o.fill(v);
            continue;
        }
        let (z2, z3) = (w[2] as i64, w[6] as i64);
        let z1 = (z2 + z3) * F0_541;
        let tmp2 = z1 - z3 * F1_847;
        let tmp3 = z1 + z2 * F0_765;
        let tmp0 = (w[0] as i64 + w[4] as i64) << CONST_BITS;
        let tmp1 = (w[0] as i64 - w[4] as i64) << CONST_BITS;
        let (t10, t13, t11, t12) = (tmp0 + tmp3, tmp0 - tmp3, tmp1 + tmp2, tmp1 - tmp2);
        let (o0, o1, o2, o3) = odd(w[7] as i64, w[5] as i64, w[3] as i64, w[1] as i64);
        let n = CONST_BITS + PASS1_BITS + 3;
        o[0] = idct_range_limit(descale(t10 + o3, n));
        o[7] = idct_range_limit(descale(t10 - o3, n));
        o[1] = idct_range_limit(descale(t11 + o2, n));
        o[6] = idct_range_limit(descale(t11 - o2, n));
        o[2] = idct_range_limit(descale(t12 + o1, n));
        o[5] = idct_range_limit(descale(t12 - o1, n));
        o[3] = idct_range_limit(descale(t13 + o0, n));
        o[4] = idct_range_limit(descale(t13 - o0, n));
    }
}

/// A component's samples: `w` x `h`, row-major.
pub struct Plane {
    pub w: usize,
    pub h: usize,
    pub data: Vec<u8>,
}

/// jdsample.c h2v1_fancy_upsample: doubles the width; the 2 outputs of input `i` are
/// `(3*in[i] + in[i-1] + 1) >> 2` and `(3*in[i] + in[i+1] + 2) >> 2`, the first and
/// last outputs of a row are the edge samples themselves. Needs `p.w > 2`.
pub fn h2v1_fancy(p: &Plane) -> Result<Plane, JpegError> {
    let (w, h) = (p.w, p.h);
    let mut out = vec_filled(2 * w * h, 0u8)?;
    for y in 0..h {
        let i = &p.data[y * w..(y + 1) * w];
        let o = &mut out[2 * y * w..2 * (y + 1) * w];
        o[0] = i[0];
        o[1] = ((i[0] as i32 * 3 + i[1] as i32 + 2) >> 2) as u8;
        for x in 1..w - 1 {
            let v = i[x] as i32 * 3;
            o[2 * x] = ((v + i[x - 1] as i32 + 1) >> 2) as u8;
            o[2 * x + 1] = ((v + i[x + 1] as i32 + 2) >> 2) as u8;
        }
        let v = i[w - 1] as i32;
        o[2 * w - 2] = ((v * 3 + i[w - 2] as i32 + 1) >> 2) as u8;
        o[2 * w - 1] = v as u8;
    }
    Ok(Plane {
        w: 2 * w,
        h,
        data: out,
    })
}

/// jdsample.c h2v2_fancy_upsample: doubles both sizes. Column sums `3*near + far` of
/// the nearer and farther input rows (the edge row repeated past the top and bottom),
/// then `(3*this + last + 8) >> 4` and `(3*this + next + 7) >> 4`, the first and last
/// outputs of a row `(4*sum + 8) >> 4` and `(4*sum + 7) >> 4`. Needs `p.w > 2`.
pub fn h2v2_fancy(p: &Plane) -> Result<Plane, JpegError> {
    let (w, h) = (p.w, p.h);
    let mut out = vec_filled(4 * w * h, 0u8)?;
    let mut sums = vec![0i32; w];
    for y in 0..h {
        let near = &p.data[y * w..(y + 1) * w];
        for v in 0..2 {
            let fy = if v == 0 {
                y.saturating_sub(1)
            } else {
                (y + 1).min(h - 1)
            };
            let far = &p.data[fy * w..(fy + 1) * w];
            for x in 0..w {
                sums[x] = near[x] as i32 * 3 + far[x] as i32;
            }
            let o = &mut out[(2 * y + v) * 2 * w..(2 * y + v + 1) * 2 * w];
            o[0] = ((sums[0] * 4 + 8) >> 4) as u8;
            o[1] = ((sums[0] * 3 + sums[1] + 7) >> 4) as u8;
            for x in 1..w - 1 {
                o[2 * x] = ((sums[x] * 3 + sums[x - 1] + 8) >> 4) as u8;
                o[2 * x + 1] = ((sums[x] * 3 + sums[x + 1] + 7) >> 4) as u8;
            }
            o[2 * w - 2] = ((sums[w - 1] * 3 + sums[w - 2] + 8) >> 4) as u8;
            o[2 * w - 1] = ((sums[w - 1] * 4 + 7) >> 4) as u8;
        }
    }
    Ok(Plane {
        w: 2 * w,
        h: 2 * h,
        data: out,
    })
}

/// jdsample.c h1v2_fancy_upsample: doubles the height; `(3*near + far + 1) >> 2` for
/// the upper output row, `+ 2` for the lower, the edge row repeated.
pub fn h1v2_fancy(p: &Plane) -> Result<Plane, JpegError> {
    let (w, h) = (p.w, p.h);
    let mut out = vec_filled(2 * w * h, 0u8)?;
    for y in 0..h {
        let near = &p.data[y * w..(y + 1) * w];
        for v in 0..2 {
            let (fy, bias) = if v == 0 {
                (y.saturating_sub(1), 1)
            } else {
                ((y + 1).min(h - 1), 2)
            };
            let far = &p.data[fy * w..(fy + 1) * w];
            let o = &mut out[(2 * y + v) * w..(2 * y + v + 1) * w];
            for x in 0..w {
                o[x] = ((near[x] as i32 * 3 + far[x] as i32 + bias) >> 2) as u8;
            }
        }
    }
    Ok(Plane {
        w,
        h: 2 * h,
        data: out,
    })
}

/// jdsample.c int_upsample (and h2v1/h2v2_upsample): each sample repeated `hx` x `vx`.
pub fn replicate(p: &Plane, hx: usize, vx: usize) -> Result<Plane, JpegError> {
    let (w, h) = (p.w * hx, p.h * vx);
    let mut out = vec_filled(w * h, 0u8)?;
    for y in 0..h {
        let i = &p.data[(y / vx) * p.w..(y / vx + 1) * p.w];
        for x in 0..w {
            out[y * w + x] = i[x / hx];
        }
    }
    Ok(Plane { w, h, data: out })
}

/// Upsamples a component by (`hx`, `vx`) as libjpeg's default (fancy) upsampler.
pub fn upsample(p: Plane, hx: usize, vx: usize) -> Result<Plane, JpegError> {
    match (hx, vx) {
        (1, 1) => Ok(p),
        (2, 1) if p.w > 2 => h2v1_fancy(&p),
        (2, 2) if p.w > 2 => h2v2_fancy(&p),
        (1, 2) => h1v2_fancy(&p),
        _ => replicate(&p, hx, vx),
    }
}

/// jdcolor.c ycc_rgb_convert's tables (SCALEBITS 16): (Cr->R, Cb->B, Cr->G, Cb->G).
fn ycc_tables() -> ([i32; 256], [i32; 256], [i64; 256], [i64; 256]) {
    const SCALEBITS: u32 = 16;
    const ONE_HALF: i64 = 1 << (SCALEBITS - 1);
    let fix = |x: f64| (x * (1i64 << SCALEBITS) as f64 + 0.5) as i64;
    let mut cr_r = [0i32; 256];
    let mut cb_b = [0i32; 256];
    let mut cr_g = [0i64; 256];
    let mut cb_g = [0i64; 256];
    for i in 0..256 {
        let x = i as i64 - 128;
        cr_r[i] = ((fix(1.40200) * x + ONE_HALF) >> SCALEBITS) as i32;
        cb_b[i] = ((fix(1.77200) * x + ONE_HALF) >> SCALEBITS) as i32;
        cr_g[i] = -fix(0.71414) * x;
        cb_g[i] = -fix(0.34414) * x + ONE_HALF;
    }
    (cr_r, cb_b, cr_g, cb_g)
}

/// jdcolor.c ycc_rgb_convert for one sample.
pub fn ycc_to_rgb(y: u8, cb: u8, cr: u8) -> [u8; 3] {
    use std::sync::OnceLock;
    type Tables = ([i32; 256], [i32; 256], [i64; 256], [i64; 256]);
    static TABLES: OnceLock<Tables> = OnceLock::new();
    let (cr_r, cb_b, cr_g, cb_g) = TABLES.get_or_init(ycc_tables);
    let y = y as i32;
    let (cb, cr) = (cb as usize, cr as usize);
    let g = ((cb_g[cb] + cr_g[cr]) >> 16) as i32;
    let lim = |v: i32| v.clamp(0, 255) as u8;
    [lim(y + cr_r[cr]), lim(y + g), lim(y + cb_b[cb])]
}

fn finish(
    f: Frame,
    qt: &[Option<[u16; 64]>; 4],
    saw_jfif: bool,
    adobe_transform: Option<u8>,
) -> Result<Decoded, JpegError> {
    let n = f.comps.len();
    // jdapimin.c default_decompress_parms: the colour space libjpeg assumes.
    let rgb_direct = match n {
        1 => false,
        3 => {
            if saw_jfif {
                false
            } else if let Some(t) = adobe_transform {
                t == 0
            } else {
                let ids: Vec<u8> = f.comps.iter().map(|c| c.id).collect();
                ids == [b'R', b'G', b'B']
            }
        }
        4 => {
            return Err(JpegError::FourComponents(match adobe_transform {
                Some(0) | None => "CMYK",
                _ => "YCCK",
            }))
        }
        _ => return Err(JpegError::Unsupported("2 colour components")),
    };
    let mut planes = Vec::with_capacity(n);
    for c in &f.comps {
        let quant = qt[c.tq]
            .as_ref()
            .ok_or(JpegError::Corrupt("undefined quantization table"))?;
        let (pw, ph) = (c.pbw * 8, c.pbh * 8);
        let mut full = vec_filled(pw * ph, 0u8)?;
        for by in 0..c.bh {
            for bx in 0..c.bw {
                let off = (by * c.pbw + bx) * 64;
                let o = by * 8 * pw + bx * 8;
                idct_islow(&c.coefs[off..off + 64], quant, &mut full[o..], pw);
            }
        }
        // Crop to the component's samples.
        let mut data = vec_filled(c.dw * c.dh, 0u8)?;
        for y in 0..c.dh {
            data[y * c.dw..(y + 1) * c.dw].copy_from_slice(&full[y * pw..y * pw + c.dw]);
        }
        drop(full);
        let p = Plane {
            w: c.dw,
            h: c.dh,
            data,
        };
        planes.push(upsample(p, f.hmax / c.h, f.vmax / c.v)?);
    }
    let (w, h) = (f.width, f.height);
    let channels = if n == 1 { 1 } else { 3 };
    let mut data = vec_filled(w * h * channels, 0u8)?;
    for y in 0..h {
        for x in 0..w {
            let s = |p: &Plane| p.data[y * p.w + x];
            let o = (y * w + x) * channels;
            if n == 1 {
                data[o] = s(&planes[0]);
            } else {
                let (a, b, c) = (s(&planes[0]), s(&planes[1]), s(&planes[2]));
                let rgb = if rgb_direct {
                    [a, b, c]
                } else {
                    ycc_to_rgb(a, b, c)
                };
                data[o..o + 3].copy_from_slice(&rgb);
            }
        }
    }
    Ok(Decoded {
        width: w,
        height: h,
        channels,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// jdsample.c's formulas written out per output sample, edges by clamping the
    /// input index: the reference the fast upsamplers must equal.
    fn slow_fancy(p: &Plane, hx: usize, vx: usize) -> Plane {
        let (w, h) = (p.w as isize, p.h as isize);
        let at = |x: isize, y: isize| {
            p.data[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize] as i32
        };
        let (ow, oh) = (p.w * hx, p.h * vx);
        let mut data = vec![0u8; ow * oh];
        for oy in 0..oh as isize {
            for ox in 0..ow as isize {
                let (x, y) = (ox / hx as isize, oy / vx as isize);
                let v = match (hx, vx) {
                    (2, 1) => {
                        let (nx, bias) = if ox % 2 == 0 { (x - 1, 1) } else { (x + 1, 2) };
                        (3 * at(x, y) + at(nx, y) + bias) >> 2
                    }
                    (1, 2) => {
                        let (ny, bias) = if oy % 2 == 0 { (y - 1, 1) } else { (y + 1, 2) };
                        (3 * at(x, y) + at(x, ny) + bias) >> 2
                    }
                    (2, 2) => {
                        let ny = if oy % 2 == 0 { y - 1 } else { y + 1 };
                        let col = |cx: isize| 3 * at(cx, y) + at(cx, ny);
                        let (nx, bias) = if ox % 2 == 0 { (x - 1, 8) } else { (x + 1, 7) };
                        (3 * col(x) + col(nx) + bias) >> 4
                    }
                    _ => unreachable!(),
                };
                data[(oy * ow as isize + ox) as usize] = v as u8;
            }
        }
        Plane { w: ow, h: oh, data }
    }

    fn noise_plane(w: usize, h: usize, seed: u32) -> Plane {
        let mut s = seed.wrapping_mul(2654435761).wrapping_add(1);
        let data = (0..w * h)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s >> 24) as u8
            })
            .collect();
        Plane { w, h, data }
    }

    #[test]
    fn fancy_upsamplers_equal_jdsample_formulas() {
        for (w, h) in [(3, 1), (3, 2), (4, 3), (5, 5), (17, 9), (9, 16)] {
            for (hx, vx) in [(2, 1), (2, 2), (1, 2)] {
                let p = noise_plane(w, h, (w * 31 + h * 7 + hx * 3 + vx) as u32);
                let fast = upsample(
                    Plane {
                        w,
                        h,
                        data: p.data.clone(),
                    },
                    hx,
                    vx,
                )
                .unwrap();
                let slow = slow_fancy(&p, hx, vx);
                assert_eq!((fast.w, fast.h), (slow.w, slow.h));
                assert_eq!(fast.data, slow.data, "{w}x{h} by {hx}x{vx}");
            }
        }
    }

    #[test]
    fn narrow_planes_replicate_as_libjpeg() {
        // libjpeg uses plain replication for h2v1/h2v2 when a row has 2 samples or fewer.
        let p = Plane {
            w: 2,
            h: 1,
            data: vec![10, 200],
        };
        let out = upsample(p, 2, 1).unwrap();
        assert_eq!(out.data, vec![10, 10, 200, 200]);
    }

    #[test]
    fn ycc_tables_match_jdcolor() {
        // Grey stays grey; the extremes clamp; a known libjpeg value.
        assert_eq!(ycc_to_rgb(128, 128, 128), [128, 128, 128]);
        assert_eq!(ycc_to_rgb(255, 255, 255), [255, 121, 255]);
        assert_eq!(ycc_to_rgb(0, 0, 0), [0, 135, 0]);
    }

    #[test]
    fn idct_of_dc_only_block_is_flat() {
        let mut coefs = [0i16; 64];
        coefs[0] = 10;
        let mut q = [1u16; 64];
        q[0] = 8;
        let mut out = [0u8; 64];
        idct_islow(&coefs, &q, &mut out, 8);
        // 10 * 8 / 8 = 10 above the 128 centre.
        assert!(out.iter().all(|&v| v == 138));
    }

    #[test]
    fn hostile_headers_give_errors() {
        assert!(matches!(
            decode(&[], 1 << 20),
            Err(JpegError::Truncated("no start-of-image marker"))
        ));
        assert!(matches!(
            decode(&[0xFF, 0xD8], 1 << 20),
            Err(JpegError::Truncated("no end-of-image marker"))
        ));
        assert!(matches!(
            decode(&[0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x01], 1 << 20),
            Err(JpegError::Corrupt("marker segment length below 2"))
        ));
        // A frame of 65535 x 65535 is refused before allocating.
        let sof = [
            0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 0xFF, 0xFF, 0xFF, 0xFF, 1, 1, 0x11, 0,
        ];
        assert!(matches!(
            decode(&sof, 1 << 20),
            Err(JpegError::TooLarge { .. })
        ));
    }
}
