//! A JPEG checked whole before it is decoded. JPEG decoders paint what they cannot read
//! rather than fail: the rows of a file cut short come out flat grey, and bytes missing from
//! the middle of a scan put the entropy decoder out of step, so that it reaches the scan's
//! end early, pads with zeros and paints the remaining blocks from them (garbled and flat
//! rows, without an error, in the decoder's strict mode too).
//!
//! So the file's markers are walked to its end-of-image marker, and every sequential Huffman
//! scan (baseline and extended JPEG: nearly every camera's and encoder's) has its codes
//! decoded, without the inverse transforms, block by block: a scan whose data ends before
//! its last block, that holds a code its tables lack, runs a block past its 64 coefficients
//! or misses a restart marker is damaged. Progressive and arithmetic-coded scans are walked
//! to their end only.

/// Walks a JPEG's markers from start to end of image (see the module documentation): every
/// segment and every scan's entropy-coded data must be there in full, and sequential scans
/// must decode.
pub(crate) fn check_jpeg_complete(bytes: &[u8]) -> Result<(), String> {
    let truncated = || "the JPEG is truncated (it ends before its end-of-image marker)".to_string();
    if bytes.len() < 2 || bytes[..2] != [0xFF, 0xD8] {
        return Err("not a JPEG image (no start-of-image marker)".into());
    }
    let mut tables = Tables::default();
    let mut i = 2;
    loop {
        if i >= bytes.len() {
            return Err(truncated());
        }
        if bytes[i] != 0xFF {
            return Err(format!("the JPEG is damaged: no marker at byte {i}"));
        }
        while bytes.get(i) == Some(&0xFF) {
            i += 1;
        }
        let Some(&marker) = bytes.get(i) else { return Err(truncated()) };
        i += 1;
        match marker {
            0xD9 => return Ok(()),
            // Markers without a length: restart markers and TEM.
            0xD0..=0xD7 | 0x01 => continue,
            0x00 | 0xD8 => return Err(format!("the JPEG is damaged: unexpected marker at byte {}", i - 2)),
            _ => {}
        }
        let Some(length) = bytes.get(i..i + 2).map(|b| usize::from(u16::from_be_bytes([b[0], b[1]]))) else {
            return Err(truncated());
        };
        if length < 2 {
            return Err(format!("the JPEG is damaged: a segment of length {length} at byte {i}"));
        }
        let segment = bytes.get(i + 2..i + length).ok_or_else(truncated)?;
        let start = i;
        let damaged =
            move |what: String| format!("the JPEG is damaged: {what} (the segment at byte {start})");
        tables.read(marker, segment).map_err(damaged)?;
        i += length;
        if marker == 0xDA {
            // A file cut short is named as such, before its last scan is decoded.
            let end = scan_end(bytes, i).ok_or_else(truncated)?;
            if let Some(scan) = tables.scan(segment).map_err(damaged)? {
                scan.decode(&bytes[i..]).map_err(|what| format!("the JPEG is damaged: {what}"))?;
            }
            i = end;
        }
    }
}

/// Where the entropy-coded data from `at` ends: the next marker but a restart marker (0xFF
/// is followed there by 0x00, a stuffed byte, or a restart marker), if the file has one.
fn scan_end(bytes: &[u8], mut at: usize) -> Option<usize> {
    loop {
        let mut j = at + bytes[at..].iter().position(|&b| b == 0xFF)?;
        while bytes.get(j + 1) == Some(&0xFF) {
            j += 1;
        }
        match bytes.get(j + 1)? {
            0x00 | 0xD0..=0xD7 => at = j + 2,
            _ => return Some(j),
        }
    }
}

/// What the segments before a scan have said: the frame, the Huffman tables in force and
/// the restart interval.
#[derive(Default)]
struct Tables {
    /// The frame, if it is a sequential Huffman frame (SOF0, SOF1); None before one or for
    /// another kind.
    frame: Option<Frame>,
    /// DC and AC tables by id (0 to 3).
    huffman: [[Option<Huffman>; 4]; 2],
    /// Quantisation tables by id (0 to 3), in zigzag order as the file stores them.
    quantisation: [Option<[u16; 64]>; 4],
    /// MCUs between restart markers (0: none).
    restart: usize,
}

struct Frame {
    /// Bits per sample (8 or 12).
    precision: u32,
    width: usize,
    height: usize,
    /// Per component: its id, horizontal and vertical sampling, quantisation table.
    components: Vec<(u8, usize, usize, usize)>,
}

impl Tables {
    /// Takes in what the segment of `marker` defines.
    fn read(&mut self, marker: u8, segment: &[u8]) -> Result<(), String> {
        match marker {
            // Sequential Huffman frames.
            0xC0 | 0xC1 => self.frame = Some(frame(segment)?),
            // Other frames (progressive, lossless, arithmetic-coded) are walked only.
            0xC2 | 0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => self.frame = None,
            0xC4 => {
                let mut rest = segment;
                while !rest.is_empty() {
                    let (class, id) = (usize::from(rest[0] >> 4), usize::from(rest[0] & 15));
                    let (table, used) = Huffman::new(&rest[1..])?;
                    if class > 1 || id > 3 {
                        return Err(format!("a Huffman table of class {class} and id {id}"));
                    }
                    self.huffman[class][id] = Some(table);
                    rest = &rest[1 + used..];
                }
            }
            0xDB => {
                let mut rest = segment;
                while !rest.is_empty() {
                    let (wide, id) = (rest[0] >> 4 == 1, usize::from(rest[0] & 15));
                    let size = if wide { 128 } else { 64 };
                    let values = rest.get(1..1 + size).ok_or("a quantisation table cut short")?;
                    let mut table = [0u16; 64];
                    for (k, q) in table.iter_mut().enumerate() {
                        *q = match wide {
                            true => u16::from_be_bytes([values[2 * k], values[2 * k + 1]]),
                            false => values[k].into(),
                        };
                    }
                    *self
                        .quantisation
                        .get_mut(id)
                        .ok_or_else(|| format!("a quantisation table of id {id}"))? = Some(table);
                    rest = &rest[1 + size..];
                }
            }
            0xDD => {
                let ri = segment.get(..2).ok_or("a restart interval without its value")?;
                self.restart = usize::from(u16::from_be_bytes([ri[0], ri[1]]));
            }
            _ => {}
        }
        Ok(())
    }

    /// The scan a start-of-scan `segment` opens, if it is one that is checked (in a
    /// sequential Huffman frame of known height).
    fn scan(&self, segment: &[u8]) -> Result<Option<Scan<'_>>, String> {
        let Some(frame) = self.frame.as_ref().filter(|f| f.height > 0) else { return Ok(None) };
        let count = usize::from(*segment.first().ok_or("an empty scan header")?);
        let selectors = segment.get(1..1 + 2 * count).ok_or("a scan header shorter than its components")?;
        let mut components = Vec::with_capacity(count);
        for pair in selectors.chunks_exact(2) {
            let &(_, h, v, q) = frame
                .components
                .iter()
                .find(|c| c.0 == pair[0])
                .ok_or_else(|| format!("a scan of component {}, which the frame lacks", pair[0]))?;
            let table = |class: usize, id: u8| {
                // A damaged selector may name any of 16 ids; the file defines at most 4.
                self.huffman[class].get(usize::from(id)).and_then(Option::as_ref).ok_or_else(|| {
                    format!("a scan that uses Huffman table {id}, which the file does not define")
                })
            };
            let quantisation = self.quantisation.get(q).copied().flatten().ok_or_else(|| {
                format!("a component quantised by table {q}, which the file does not define")
            })?;
            components.push(ScanComponent {
                sampling: (h, v),
                dc: table(0, pair[1] >> 4)?,
                ac: table(1, pair[1] & 15)?,
                quantisation,
            });
        }
        Ok(Some(Scan { frame, components, restart: self.restart }))
    }
}

/// A sequential frame header: precision, height, width, then per component its id,
/// sampling factors and quantisation table.
fn frame(segment: &[u8]) -> Result<Frame, String> {
    let head = segment.get(..6).ok_or("a frame header cut short")?;
    let (height, width) = (u16::from_be_bytes([head[1], head[2]]), u16::from_be_bytes([head[3], head[4]]));
    let count = usize::from(head[5]);
    let listed = segment.get(6..6 + 3 * count).ok_or("a frame header shorter than its components")?;
    let components: Vec<(u8, usize, usize, usize)> = listed
        .chunks_exact(3)
        .map(|c| (c[0], usize::from(c[1] >> 4), usize::from(c[1] & 15), usize::from(c[2])))
        .collect();
    let sampling = |&(_, h, v, _): &(u8, usize, usize, usize)| (1..=4).contains(&h) && (1..=4).contains(&v);
    if components.is_empty() || !components.iter().all(sampling) {
        return Err("a frame without components, or with a sampling factor outside 1 to 4".into());
    }
    if head[0] != 8 && head[0] != 12 {
        return Err(format!("a sequential frame of {} bits per sample", head[0]));
    }
    Ok(Frame {
        precision: head[0].into(),
        width: usize::from(width),
        height: usize::from(height),
        components,
    })
}

/// A Huffman table as the standard decodes it (ITU T.81, F.2.2.3): per code length, the
/// largest code, and where its codes' values start.
struct Huffman {
    max_code: [i32; 17],
    first_code: [i32; 17],
    first_value: [usize; 17],
    values: Vec<u8>,
}

impl Huffman {
    /// The table at the start of `bytes` (16 counts, then the values), and the bytes it
    /// took.
    fn new(bytes: &[u8]) -> Result<(Huffman, usize), String> {
        let counts = bytes.get(..16).ok_or("a Huffman table cut short")?;
        let total: usize = counts.iter().map(|&c| usize::from(c)).sum();
        let values = bytes.get(16..16 + total).ok_or("a Huffman table shorter than its counts")?.to_vec();
        let mut table = Huffman { max_code: [-1; 17], first_code: [0; 17], first_value: [0; 17], values };
        let (mut code, mut k) = (0i32, 0usize);
        for length in 1..=16 {
            let count = usize::from(counts[length - 1]);
            if count > 0 {
                table.first_value[length] = k;
                table.first_code[length] = code;
                code += count as i32;
                k += count;
                table.max_code[length] = code - 1;
                if code > 1 << length {
                    return Err("a Huffman table with more codes than its lengths allow".into());
                }
            }
            code <<= 1;
        }
        Ok((table, 16 + total))
    }

    /// The next value in `bits`.
    fn decode(&self, bits: &mut Bits) -> Result<u8, String> {
        let (next, available) = bits.peek16();
        for length in 1..=16 {
            let code = i32::from(next >> (16 - length));
            if code <= self.max_code[length] {
                if length as u32 > available {
                    break;
                }
                bits.take(length as u32)?;
                return Ok(self.values[self.first_value[length] + (code - self.first_code[length]) as usize]);
            }
        }
        match available {
            16 => Err("its scan holds a code its Huffman tables lack".into()),
            _ => Err(ENDS_EARLY.into()),
        }
    }
}

/// One component of a sequential scan.
struct ScanComponent<'a> {
    sampling: (usize, usize),
    dc: &'a Huffman,
    ac: &'a Huffman,
    quantisation: [u16; 64],
}

/// A sequential scan: its components and the restart interval.
struct Scan<'a> {
    frame: &'a Frame,
    components: Vec<ScanComponent<'a>>,
    restart: usize,
}

impl Scan<'_> {
    /// Decodes every block of the scan from `data` (the file from the scan's first byte).
    fn decode(&self, data: &[u8]) -> Result<(), String> {
        let frame = self.frame;
        let hmax = frame.components.iter().map(|c| c.1).max().unwrap_or(1);
        let vmax = frame.components.iter().map(|c| c.2).max().unwrap_or(1);
        // One component alone: its own blocks, one per MCU; interleaved: h × v blocks of
        // each component per MCU.
        let (mcus, per_mcu): (usize, Vec<(usize, usize)>) = match self.components.as_slice() {
            [one] => {
                let (h, v) = one.sampling;
                let across = (frame.width * h).div_ceil(hmax).div_ceil(8);
                let down = (frame.height * v).div_ceil(vmax).div_ceil(8);
                (across * down, vec![(0, 1)])
            }
            many => {
                let across = frame.width.div_ceil(8 * hmax);
                let down = frame.height.div_ceil(8 * vmax);
                (
                    across * down,
                    many.iter().enumerate().map(|(c, s)| (c, s.sampling.0 * s.sampling.1)).collect(),
                )
            }
        };
        // A coefficient's magnitude: at most 1024 for 8-bit samples (8 × the level-shifted
        // sample range), 16384 for 12-bit; twice that leaves room for any encoder's rounding.
        let bound = 2i64 << (frame.precision + 3);
        let mut bits = Bits { data, at: 0, buffer: 0, count: 0 };
        let mut predictions = vec![0i64; self.components.len()];
        for mcu in 0..mcus {
            if self.restart > 0 && mcu > 0 && mcu % self.restart == 0 {
                bits.restart((mcu / self.restart - 1) % 8, mcu)?;
                predictions.iter_mut().for_each(|p| *p = 0);
            }
            for &(c, blocks) in &per_mcu {
                let component = &self.components[c];
                for _ in 0..blocks {
                    block(&mut bits, component, &mut predictions[c], (frame.precision, bound))
                        .map_err(|why| format!("{why}, in block {mcu} of {mcus}"))?;
                }
            }
        }
        bits.padding()?;
        // Past the last block only the rest of its byte (padding) may come before the marker:
        // whole bytes left over mean the codes were read out of step.
        let left = scan_end(data, bits.at).unwrap_or(data.len()) - bits.at;
        if left > 0 {
            return Err(format!(
                "its scan holds {left} bytes past its last block (bytes are missing before them)"
            ));
        }
        Ok(())
    }
}

/// One block's codes: the DC difference, then AC run/size pairs up to the end of block or
/// the 63rd coefficient. The codes of data read out of step (bytes missing before them)
/// soon call for more bits than a coefficient has (`precision` + 3 for DC, + 2 for AC),
/// drive the DC prediction or a coefficient past `bound` once dequantised, or run a block
/// past its 64 coefficients.
fn block(
    bits: &mut Bits,
    component: &ScanComponent,
    prediction: &mut i64,
    (precision, bound): (u32, i64),
) -> Result<(), String> {
    let out_of_step = |what: &str| Err(format!("its scan holds {what} (bytes are missing before it?)"));
    let size = u32::from(component.dc.decode(bits)?);
    if size > precision + 3 {
        return out_of_step(&format!("a DC difference of {size} bits"));
    }
    *prediction += extend(bits.take(size)?, size);
    if (*prediction * i64::from(component.quantisation[0])).abs() > bound {
        return out_of_step("a DC value beyond any sample's");
    }
    let mut k = 1;
    while k < 64 {
        let pair = component.ac.decode(bits)?;
        let (run, size) = (usize::from(pair >> 4), u32::from(pair & 15));
        if size == 0 {
            if run == 15 {
                k += 16;
                continue;
            }
            break;
        }
        k += run;
        if k > 63 {
            return Err("its scan runs a block past its 64 coefficients".into());
        }
        if size > precision + 2 {
            return out_of_step(&format!("an AC coefficient of {size} bits"));
        }
        let value = extend(bits.take(size)?, size);
        if (value * i64::from(component.quantisation[k])).abs() > bound {
            return out_of_step("an AC coefficient beyond any sample's");
        }
        k += 1;
    }
    Ok(())
}

/// The signed value of the `size` bits `raw` (ITU T.81, F.12: EXTEND).
fn extend(raw: u32, size: u32) -> i64 {
    match size {
        0 => 0,
        _ if raw < 1 << (size - 1) => i64::from(raw) - (1i64 << size) + 1,
        _ => i64::from(raw),
    }
}

/// Why a scan that runs out of data is refused.
const ENDS_EARLY: &str = "its scan's data ends before its last block (bytes are missing)";

/// The bits of entropy-coded data, stuffed bytes (0xFF 0x00) read as 0xFF; a marker ends
/// them.
struct Bits<'a> {
    data: &'a [u8],
    at: usize,
    buffer: u64,
    count: u32,
}

impl Bits<'_> {
    /// Reads bytes until `n` bits are buffered or the data ends; whether they are.
    fn fill(&mut self, n: u32) -> bool {
        while self.count < n {
            let byte = match (self.data.get(self.at), self.data.get(self.at + 1)) {
                (Some(0xFF), Some(0x00)) => {
                    self.at += 2;
                    0xFF
                }
                (Some(&b), _) if b != 0xFF => {
                    self.at += 1;
                    b
                }
                _ => return false,
            };
            self.buffer = (self.buffer << 8) | u64::from(byte);
            self.count += 8;
        }
        true
    }

    /// The next 16 bits without taking them (zeros past the data's end), and how many of
    /// them the data holds.
    fn peek16(&mut self) -> (u16, u32) {
        self.fill(16);
        let available = self.count.min(16);
        let top = (self.buffer >> (self.count - available)) & ((1u64 << available) - 1);
        ((top << (16 - available)) as u16, available)
    }

    /// The next `n` (at most 16) bits.
    fn take(&mut self, n: u32) -> Result<u32, String> {
        if !self.fill(n) {
            return Err(ENDS_EARLY.into());
        }
        self.count -= n;
        Ok(((self.buffer >> self.count) & ((1u64 << n) - 1)) as u32)
    }

    /// The rest of the byte, which must be the padding the standard asks for: 1 bits.
    fn padding(&mut self) -> Result<(), String> {
        let rest = (self.count % 8) as u64;
        let ones = (1u64 << rest) - 1;
        if self.buffer & ones != ones {
            return Err(
                "its scan's last byte is not padded with 1 bits (bytes are missing before it?)".into()
            );
        }
        self.count = 0;
        Ok(())
    }

    /// Skips the padding and the restart marker `n` that must come before `mcu`.
    fn restart(&mut self, n: usize, mcu: usize) -> Result<(), String> {
        self.padding()?;
        while self.data.get(self.at) == Some(&0xFF) && self.data.get(self.at + 1) == Some(&0xFF) {
            self.at += 1;
        }
        if self.data.get(self.at..self.at + 2) != Some(&[0xFF, 0xD0 + n as u8]) {
            return Err(format!("its scan lacks restart marker {n} before block {mcu} (bytes are missing)"));
        }
        self.at += 2;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encoded(image: image::DynamicImage) -> Vec<u8> {
        let mut bytes = Vec::new();
        image.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Jpeg).unwrap();
        bytes
    }

    /// Every JPEG the encoder writes (colour and grey, sizes that are and are not whole
    /// MCUs) passes; the same with a run of bytes taken out of its scan mostly does not.
    /// Huffman codes fall back into step after a loss, so a cut can decode to the scan's end:
    /// 212 of 734 cuts of these small images still pass (a known limit, see
    /// docs/reliability.md); this guards the share refused.
    #[test]
    fn scans_with_bytes_missing_are_refused() {
        // Textured, as photographs are: a smooth gradient's blocks are a few bits each, and
        // codes read out of step decode as such blocks as often as not.
        let noise = |x: u32, y: u32, c: u32| {
            ((x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ c.wrapping_mul(83_492_791)) >> 7)
                as u8
        };
        let colour = image::RgbImage::from_fn(37, 21, |x, y| {
            image::Rgb([noise(x, y, 1), noise(x, y, 2), noise(x, y, 3)])
        });
        let grey = image::GrayImage::from_fn(16, 9, |x, y| image::Luma([noise(x, y, 0)]));
        let (mut cuts, mut passed) = (0, Vec::new());
        for bytes in [encoded(colour.into()), encoded(grey.into())] {
            check_jpeg_complete(&bytes).unwrap();
            let scan = bytes.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap() + 14;
            let end = bytes.len() - 2;
            for at in (scan..end).step_by(3) {
                for n in [1, 2, 5, 16] {
                    if at + n > end {
                        continue;
                    }
                    let cut = [&bytes[..at], &bytes[at + n..]].concat();
                    cuts += 1;
                    if check_jpeg_complete(&cut).is_ok() {
                        passed.push((n, at, bytes.len()));
                    }
                }
            }
        }
        assert!(passed.len() * 10 <= cuts * 3, "{} of {cuts} cuts passed: {passed:?}", passed.len());
    }
}
