//! A JPEG checked whole before it is decoded. JPEG decoders paint what they cannot read
//! rather than fail: the rows of a file cut short come out flat grey, and bytes missing from
//! the middle of a scan put the entropy decoder out of step, so that it reaches the scan's
//! end early, pads with zeros and paints the remaining blocks from them (garbled and flat
//! rows, without an error, in the decoder's strict mode too).
//!
//! So the file's markers are walked to its end-of-image marker, and every Huffman scan has
//! its codes decoded, without the inverse transforms, block by block: sequential scans
//! (baseline and extended JPEG: nearly every camera's and encoder's) and progressive ones
//! (ITU T.81 Annex G: DC first and refinement scans, AC first and refinement scans with their
//! end-of-band runs). A scan whose data ends before its last block, that holds a code its
//! tables lack, runs a block past its 64 coefficients or its spectral band, codes a value no
//! sample could have or misses a restart marker is damaged. Progressive scans keep, per block,
//! which coefficients earlier scans made nonzero: refinement scans code a correction bit for
//! each of those. Arithmetic-coded (and lossless, hierarchical) scans are walked to their end
//! only.
use std::cell::RefCell;

/// Walks a JPEG's markers from start to end of image (see the module documentation): every
/// segment and every scan's entropy-coded data must be there in full, and Huffman scans
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
    /// The frame, if it is a Huffman frame, sequential or progressive (SOF0 to SOF2); None
    /// before one or for another kind.
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
    progressive: bool,
    /// Progressive frames: per component, per block of its own grid, which AC coefficients
    /// (bit k for zigzag position k) earlier scans made nonzero. A component's is made when
    /// its DC first scan has decoded, which proves the file holds that many blocks (a bit
    /// each at least), so that a header's bogus size cannot make it huge.
    history: RefCell<Vec<Vec<u64>>>,
}

impl Frame {
    /// The blocks across and down a component of sampling `h` × `v` covers on its own
    /// (a scan of it alone codes these; interleaved scans pad it to whole MCUs).
    fn blocks(&self, (h, v): (usize, usize)) -> (usize, usize) {
        let hmax = self.components.iter().map(|c| c.1).max().unwrap_or(1);
        let vmax = self.components.iter().map(|c| c.2).max().unwrap_or(1);
        ((self.width * h).div_ceil(hmax).div_ceil(8), (self.height * v).div_ceil(vmax).div_ceil(8))
    }
}

impl Tables {
    /// Takes in what the segment of `marker` defines.
    fn read(&mut self, marker: u8, segment: &[u8]) -> Result<(), String> {
        match marker {
            // Huffman frames: sequential, progressive.
            0xC0 | 0xC1 => self.frame = Some(frame(segment, false)?),
            0xC2 => self.frame = Some(frame(segment, true)?),
            // Other frames (lossless, hierarchical, arithmetic-coded) are walked only.
            0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => self.frame = None,
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

    /// The scan a start-of-scan `segment` opens, if it is one that is checked (in a Huffman
    /// frame of known height).
    fn scan(&self, segment: &[u8]) -> Result<Option<Scan<'_>>, String> {
        let Some(frame) = self.frame.as_ref().filter(|f| f.height > 0) else { return Ok(None) };
        let count = usize::from(*segment.first().ok_or("an empty scan header")?);
        let selectors = segment.get(1..1 + 2 * count).ok_or("a scan header shorter than its components")?;
        let (pass, band, low_bit) = match frame.progressive {
            true => progression(&segment[1 + 2 * count..], count)?,
            false => (Pass::Sequential, (0, 63), 0),
        };
        let (dc, ac) = pass.codes();
        let mut components = Vec::with_capacity(count);
        for pair in selectors.chunks_exact(2) {
            let index = frame
                .components
                .iter()
                .position(|c| c.0 == pair[0])
                .ok_or_else(|| format!("a scan of component {}, which the frame lacks", pair[0]))?;
            let (_, h, v, q) = frame.components[index];
            let quantisation = self.quantisation.get(q).copied().flatten().ok_or_else(|| {
                format!("a component quantised by table {q}, which the file does not define")
            })?;
            components.push(ScanComponent {
                index,
                sampling: (h, v),
                dc: self.table(0, pair[1] >> 4, dc)?,
                ac: self.table(1, pair[1] & 15, ac)?,
                quantisation,
            });
        }
        Ok(Some(Scan { frame, components, restart: self.restart, pass, band, low_bit }))
    }

    /// Huffman table `id` of `class` (0: DC, 1: AC), if the scan decodes such codes (`used`).
    /// A table it does not use may be named undefined (progressive encoders name table 0
    /// in refinement scans): one without codes stands in for it.
    fn table(&self, class: usize, id: u8, used: bool) -> Result<&Huffman, String> {
        if !used {
            return Ok(&NO_CODES);
        }
        // A damaged selector may name any of 16 ids; the file defines at most 4.
        self.huffman[class]
            .get(usize::from(id))
            .and_then(Option::as_ref)
            .ok_or_else(|| format!("a scan that uses Huffman table {id}, which the file does not define"))
    }
}

/// What a scan codes of each block (ITU T.81, G.1.2): all its coefficients (sequential), or
/// in a progressive frame its DC or a band of its AC coefficients, either their high bits
/// (first scans) or one bit more (refinement scans).
#[derive(Clone, Copy, PartialEq)]
enum Pass {
    Sequential,
    DcFirst,
    DcRefine,
    AcFirst,
    AcRefine,
}

impl Pass {
    /// Whether the scan decodes DC codes and AC codes with Huffman tables.
    fn codes(self) -> (bool, bool) {
        match self {
            Pass::Sequential => (true, true),
            Pass::DcFirst => (true, false),
            Pass::DcRefine => (false, false),
            Pass::AcFirst | Pass::AcRefine => (false, true),
        }
    }
}

/// A progressive scan of `count` components, from the end of its header (`tail`: first and
/// last coefficient, successive approximation's high and low bit): its pass, band (zigzag
/// positions) and low bit. DC and AC are never coded together, an AC scan is of one
/// component, and the low bit is at most 13 (T.81, G.1.1.1 and B.2.3).
fn progression(tail: &[u8], count: usize) -> Result<(Pass, (usize, usize), u32), String> {
    let Some(&[start, end, bits]) = tail.get(..3) else {
        return Err("a progressive scan header cut short".into());
    };
    let (start, end, high, low) = (usize::from(start), usize::from(end), bits >> 4, u32::from(bits & 15));
    let dc = start == 0;
    if end > 63 || start > end || (dc && end > 0) || (!dc && count != 1) || low > 13 {
        return Err(format!(
            "a progressive scan of coefficients {start} to {end}, from bit {low}, of {count} components"
        ));
    }
    let pass = match (dc, high) {
        (true, 0) => Pass::DcFirst,
        (true, _) => Pass::DcRefine,
        (false, 0) => Pass::AcFirst,
        (false, _) => Pass::AcRefine,
    };
    Ok((pass, (start, end), low))
}

/// A Huffman frame header: precision, height, width, then per component its id, sampling
/// factors and quantisation table.
fn frame(segment: &[u8], progressive: bool) -> Result<Frame, String> {
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
        return Err(format!("a Huffman frame of {} bits per sample", head[0]));
    }
    Ok(Frame {
        precision: head[0].into(),
        width: usize::from(width),
        height: usize::from(height),
        history: RefCell::new(vec![Vec::new(); components.len()]),
        components,
        progressive,
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

/// A table without codes, for a table a scan names but does not use.
static NO_CODES: Huffman =
    Huffman { max_code: [-1; 17], first_code: [0; 17], first_value: [0; 17], values: Vec::new() };

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

/// One component of a scan.
struct ScanComponent<'a> {
    /// Its index in the frame.
    index: usize,
    sampling: (usize, usize),
    dc: &'a Huffman,
    ac: &'a Huffman,
    quantisation: [u16; 64],
}

/// A scan: its components, the restart interval and what it codes of each block.
struct Scan<'a> {
    frame: &'a Frame,
    components: Vec<ScanComponent<'a>>,
    restart: usize,
    pass: Pass,
    /// The first and last coefficient it codes, in zigzag order.
    band: (usize, usize),
    /// Successive approximation: its values are coded divided by 2^low_bit.
    low_bit: u32,
}

/// Where the decoding of a scan stands.
struct Cursor<'a> {
    bits: Bits<'a>,
    /// Per scan component, the DC value its next difference is to.
    predictions: Vec<i64>,
    /// Progressive AC scans: the blocks ahead that an end-of-band run leaves without codes.
    eob_run: u32,
}

impl Cursor<'_> {
    /// Encoders count the blocks of a restart interval, or of the scan, in an end-of-band
    /// run: one that outlasts them was read out of step.
    fn run_ended(&self) -> Result<(), String> {
        match self.eob_run {
            0 => Ok(()),
            n => out_of_step(&format!("an end-of-band run {n} blocks longer than its blocks")),
        }
    }

    /// After the scan's last block: the end of any end-of-band run, then only the rest of
    /// its byte (padding) before the marker. Whole bytes left over mean the codes were read
    /// out of step.
    fn finish(&mut self) -> Result<(), String> {
        self.run_ended()?;
        self.bits.padding()?;
        let (data, at) = (self.bits.data, self.bits.at);
        let left = scan_end(data, at).unwrap_or(data.len()) - at;
        if left > 0 {
            return Err(format!(
                "its scan holds {left} bytes past its last block (bytes are missing before them)"
            ));
        }
        Ok(())
    }
}

impl Scan<'_> {
    /// Decodes every block of the scan from `data` (the file from the scan's first byte).
    fn decode(&self, data: &[u8]) -> Result<(), String> {
        let (mcus, per_mcu) = self.layout();
        let mut history = self.frame.history.borrow_mut();
        // An AC scan is of one component, whose blocks are its MCUs.
        let ac = matches!(self.pass, Pass::AcFirst | Pass::AcRefine);
        let own: &mut [u64] = if ac { &mut history[self.components[0].index] } else { &mut [] };
        if ac && own.len() != mcus {
            // Before its component's DC scan, which T.81 forbids and decoders let pass: there
            // is no history to refine, so the scan is walked only.
            return Ok(());
        }
        let bits = Bits { data, at: 0, buffer: 0, count: 0 };
        let mut at = Cursor { bits, predictions: vec![0; self.components.len()], eob_run: 0 };
        for mcu in 0..mcus {
            if self.restart > 0 && mcu > 0 && mcu % self.restart == 0 {
                at.run_ended()?;
                at.bits.restart((mcu / self.restart - 1) % 8, mcu)?;
                at.predictions.iter_mut().for_each(|p| *p = 0);
                at.eob_run = 0;
            }
            // DC scans keep no history.
            let mut none = 0;
            let block_history = own.get_mut(mcu).unwrap_or(&mut none);
            for &(c, blocks) in &per_mcu {
                for _ in 0..blocks {
                    self.block(&mut at, c, block_history)
                        .map_err(|why| format!("{why}, in block {mcu} of {mcus}"))?;
                }
            }
        }
        at.finish()?;
        if self.pass == Pass::DcFirst {
            // It has coded each block of its components: their histories may be as large.
            for component in &self.components {
                let (across, down) = self.frame.blocks(component.sampling);
                let own = &mut history[component.index];
                if own.is_empty() {
                    *own = vec![0; across * down];
                }
            }
        }
        Ok(())
    }

    /// The scan's MCUs, and per MCU each scan component's blocks: a component alone is
    /// coded block by block over its own grid, interleaved ones h × v blocks each per MCU
    /// over the frame's grid of MCUs.
    fn layout(&self) -> (usize, Vec<(usize, usize)>) {
        let frame = self.frame;
        match self.components.as_slice() {
            [one] => {
                let (across, down) = frame.blocks(one.sampling);
                (across * down, vec![(0, 1)])
            }
            many => {
                let hmax = frame.components.iter().map(|c| c.1).max().unwrap_or(1);
                let vmax = frame.components.iter().map(|c| c.2).max().unwrap_or(1);
                let mcus = frame.width.div_ceil(8 * hmax) * frame.height.div_ceil(8 * vmax);
                (mcus, many.iter().enumerate().map(|(c, s)| (c, s.sampling.0 * s.sampling.1)).collect())
            }
        }
    }

    /// Decodes a block of scan component `c`, whose AC coefficients made nonzero by earlier
    /// scans are `history`.
    fn block(&self, at: &mut Cursor, c: usize, history: &mut u64) -> Result<(), String> {
        let component = &self.components[c];
        // A coefficient's magnitude: at most 1024 for 8-bit samples (8 × the level-shifted
        // sample range), 16384 for 12-bit; twice that leaves room for any encoder's rounding.
        let limits = (self.frame.precision, 2i64 << (self.frame.precision + 3));
        let (bits, prediction) = (&mut at.bits, &mut at.predictions[c]);
        match self.pass {
            Pass::Sequential => sequential_block(bits, component, prediction, limits),
            Pass::DcFirst => dc_value(bits, component, prediction, self.low_bit, limits),
            // One bit a block, either value: there is nothing to check but that it is there.
            Pass::DcRefine => bits.take(1).map(drop),
            Pass::AcFirst => {
                let coding = (self.band, self.low_bit, limits);
                ac_first(bits, component, coding, history, &mut at.eob_run)
            }
            Pass::AcRefine => ac_refine(bits, component.ac, self.band, history, &mut at.eob_run),
        }
    }
}

/// One block's codes in a sequential scan: the DC difference, then AC run/size pairs up to
/// the end of block or the 63rd coefficient. The codes of data read out of step (bytes
/// missing before them) soon call for more bits than a coefficient has, drive a value past
/// any sample's, or run a block past its 64 coefficients.
fn sequential_block(
    bits: &mut Bits,
    component: &ScanComponent,
    prediction: &mut i64,
    limits: (u32, i64),
) -> Result<(), String> {
    dc_value(bits, component, prediction, 0, limits)?;
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
        ac_value(bits, size, component.quantisation[k], 0, limits)?;
        k += 1;
    }
    Ok(())
}

/// A DC difference (its size's code, then its bits), coded divided by 2^`low_bit`. Data read
/// out of step calls for more bits than a DC difference has (`precision` + 3) or drives the
/// prediction past `bound` once dequantised.
fn dc_value(
    bits: &mut Bits,
    component: &ScanComponent,
    prediction: &mut i64,
    low_bit: u32,
    (precision, bound): (u32, i64),
) -> Result<(), String> {
    let size = u32::from(component.dc.decode(bits)?);
    if size > precision + 3 {
        return out_of_step(&format!("a DC difference of {size} bits"));
    }
    *prediction += extend(bits.take(size)?, size);
    if ((*prediction << low_bit) * i64::from(component.quantisation[0])).abs() > bound {
        return out_of_step("a DC value beyond any sample's");
    }
    Ok(())
}

/// An AC coefficient's `size` bits, coded divided by 2^`low_bit`, quantised by `q`. Data read
/// out of step calls for more bits than a coefficient has (`precision` + 2) or codes a value
/// past `bound` once dequantised.
fn ac_value(
    bits: &mut Bits,
    size: u32,
    q: u16,
    low_bit: u32,
    (precision, bound): (u32, i64),
) -> Result<(), String> {
    if size > precision + 2 {
        return out_of_step(&format!("an AC coefficient of {size} bits"));
    }
    let value = extend(bits.take(size)?, size) << low_bit;
    if (value * i64::from(q)).abs() > bound {
        return out_of_step("an AC coefficient beyond any sample's");
    }
    Ok(())
}

/// One block of a progressive AC first scan (T.81, G.1.2.2): nothing if an end-of-band run
/// covers it, else run/size codes for its band's coefficients up to the band's end or an
/// end-of-band code, which starts a run over the blocks after it. Encoders code a run of
/// zeros (16 for ZRL) only before a coefficient of the band: one that passes the band's end
/// was read out of step.
fn ac_first(
    bits: &mut Bits,
    component: &ScanComponent,
    ((start, end), low_bit, limits): ((usize, usize), u32, (u32, i64)),
    history: &mut u64,
    eob_run: &mut u32,
) -> Result<(), String> {
    if *eob_run > 0 {
        *eob_run -= 1;
        return Ok(());
    }
    let mut k = start;
    while k <= end {
        let pair = component.ac.decode(bits)?;
        let (run, size) = (usize::from(pair >> 4), u32::from(pair & 15));
        if size == 0 && run < 15 {
            // The run counts this block.
            *eob_run = eob_run_length(bits, run as u32)? - 1;
            break;
        }
        k += if size == 0 { 16 } else { run };
        if k > end {
            return past_band(end);
        }
        if size > 0 {
            ac_value(bits, size, component.quantisation[k], low_bit, limits)?;
            *history |= 1 << k;
            k += 1;
        }
    }
    Ok(())
}

/// One block of a progressive AC refinement scan (T.81, G.1.2.3): a correction bit for each
/// coefficient of its band that earlier scans made nonzero, in order, and between them codes
/// for those that become nonzero (the run of zero ones to pass, a size of 1, the sign bit), up
/// to the band's end or an end-of-band code; in an end-of-band run, the correction bits
/// only. Encoders code a run only before a coefficient that becomes nonzero.
fn ac_refine(
    bits: &mut Bits,
    table: &Huffman,
    (start, end): (usize, usize),
    history: &mut u64,
    eob_run: &mut u32,
) -> Result<(), String> {
    let mut k = start;
    while *eob_run == 0 && k <= end {
        let pair = table.decode(bits)?;
        let (run, size) = (u32::from(pair >> 4), pair & 15);
        match size {
            0 if run < 15 => {
                // The run counts this block, whose correction bits follow.
                *eob_run = eob_run_length(bits, run)?;
                break;
            }
            0 => {}
            1 => drop(bits.take(1)?),
            _ => return out_of_step(&format!("a refinement of {size} bits")),
        }
        k = pass_zeros(bits, *history, k, end, run)?;
        if k > end {
            return past_band(end);
        }
        if size == 1 {
            *history |= 1 << k;
        }
        k += 1;
    }
    if *eob_run > 0 {
        // More zeros than a band holds: to the band's end.
        pass_zeros(bits, *history, k, end, 64)?;
        *eob_run -= 1;
    }
    Ok(())
}

/// From coefficient `k` of a refinement scan's band, reads the correction bits of those
/// `history` has nonzero and passes `zeros` zero ones: the position of the zero one after
/// them, or `end` + 1 if the band has none.
fn pass_zeros(
    bits: &mut Bits,
    history: u64,
    mut k: usize,
    end: usize,
    mut zeros: u32,
) -> Result<usize, String> {
    while k <= end {
        if (history >> k) & 1 == 1 {
            bits.take(1)?;
        } else if zeros == 0 {
            break;
        } else {
            zeros -= 1;
        }
        k += 1;
    }
    Ok(k)
}

/// The blocks an end-of-band code of `r` starts a run over: 2^r, more by its next r bits.
fn eob_run_length(bits: &mut Bits, r: u32) -> Result<u32, String> {
    Ok((1 << r) + bits.take(r)?)
}

fn past_band<T>(end: usize) -> Result<T, String> {
    Err(format!("its scan runs a block past coefficient {end}, its band's last"))
}

fn out_of_step<T>(what: &str) -> Result<T, String> {
    Err(format!("its scan holds {what} (bytes are missing before it?)"))
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

    /// Progressive JPEGs of photographs (crops of scikit-image's CC0 gravel, brick and grass
    /// photographs, the colour ones with one as each channel; see tests/fixtures/README.md).
    /// Their scans follow libjpeg's progression: DC first scans, AC first scans of bands
    /// with successive approximation, then refinement scans of both.
    const PROGRESSIVE: [(&str, &[u8]); 3] = [
        // 64 × 48 grey: every scan of one component.
        ("grey", include_bytes!("../../tests/fixtures/progressive-grey.jpg")),
        // 54 × 38 colour, 4:2:0: DC scans interleaved over MCUs, the luma's AC scans over its
        // own 7 × 5 blocks (not the MCUs' 8 × 6).
        ("4:2:0", include_bytes!("../../tests/fixtures/progressive-420.jpg")),
        // 50 × 41 colour, 4:2:2, a restart marker every 2 MCUs (cjpeg -restart 2B).
        ("restart", include_bytes!("../../tests/fixtures/progressive-restart.jpg")),
    ];

    /// Each scan of a JPEG (its markers walked): its pass and where its entropy-coded data
    /// lies.
    fn scans(bytes: &[u8]) -> Vec<(Pass, std::ops::Range<usize>)> {
        let (mut found, mut at) = (Vec::new(), 2);
        while bytes[at + 1] != 0xD9 {
            let length = usize::from(u16::from_be_bytes([bytes[at + 2], bytes[at + 3]]));
            let mut next = at + 2 + length;
            if bytes[at + 1] == 0xDA {
                let header = &bytes[at + 4..next];
                let count = usize::from(header[0]);
                let (pass, _, _) = progression(&header[1 + 2 * count..], count).unwrap();
                let end = scan_end(bytes, next).unwrap();
                found.push((pass, next..end));
                next = end;
            }
            at = next;
        }
        found
    }

    fn decoded(bytes: &[u8]) -> Option<Vec<u8>> {
        image::load_from_memory_with_format(bytes, image::ImageFormat::Jpeg).ok().map(|i| i.into_bytes())
    }

    /// Takes 1, 2, 5 or 16 bytes out of the data of each `fixture`'s scans of a pass
    /// `select` picks, at every 2nd byte: the cuts, those the check let pass, and those it
    /// refused that the decoder decodes without an error to another picture.
    fn cut(fixtures: &[(&str, &[u8])], select: impl Fn(Pass) -> bool) -> (usize, Vec<String>, usize) {
        let (mut cuts, mut passed, mut garbled) = (0, Vec::new(), 0);
        for &(name, bytes) in fixtures {
            let intact = decoded(bytes).unwrap();
            for (_, data) in scans(bytes).into_iter().filter(|(pass, _)| select(*pass)) {
                for at in data.clone().step_by(2) {
                    for n in [1, 2, 5, 16].into_iter().filter(|n| at + n <= data.end) {
                        let cut = [&bytes[..at], &bytes[at + n..]].concat();
                        cuts += 1;
                        if check_jpeg_complete(&cut).is_ok() {
                            passed.push(format!("{name}: {n} at {at}"));
                        } else if decoded(&cut).is_some_and(|d| d != intact) {
                            garbled += 1;
                        }
                    }
                }
            }
        }
        (cuts, passed, garbled)
    }

    /// Asserts that at most `percent` of the cuts of scans that `select` picks pass, and
    /// that the decoder would have painted some that are refused.
    fn assert_refused(fixtures: &[(&str, &[u8])], select: impl Fn(Pass) -> bool, percent: usize) {
        let (cuts, passed, garbled) = cut(fixtures, select);
        assert!(cuts > 50, "{cuts} cuts");
        eprintln!("{} of {cuts} cuts passed, the decoder painted {garbled} of those refused", passed.len());
        assert!(passed.len() * 100 <= cuts * percent, "{} of {cuts} cuts passed: {passed:?}", passed.len());
        assert!(garbled * 2 >= cuts - passed.len(), "the decoder painted {garbled} of the refused cuts");
    }

    #[test]
    fn intact_progressive_jpegs_pass() {
        for (name, bytes) in PROGRESSIVE {
            assert!(bytes.windows(2).any(|w| w == [0xFF, 0xC2]), "{name} is progressive");
            check_jpeg_complete(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            let passes: Vec<Pass> = scans(bytes).into_iter().map(|(pass, _)| pass).collect();
            for pass in [Pass::DcFirst, Pass::DcRefine, Pass::AcFirst, Pass::AcRefine] {
                assert!(passes.contains(&pass), "{name} has no such scan");
            }
        }
    }

    /// Every JPEG in the folder `JPEG_CORPUS` names passes (false refusals are worse than
    /// missed damage). Ignored by default: run it by name, with the ignored tests included.
    #[test]
    #[ignore]
    fn many_intact_jpegs_pass() {
        let dir = std::env::var("JPEG_CORPUS").expect("JPEG_CORPUS: a folder of intact JPEGs");
        let mut count = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "jpg") {
                let bytes = std::fs::read(&path).unwrap();
                check_jpeg_complete(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                count += 1;
            }
        }
        eprintln!("{count} JPEGs pass");
    }

    #[test]
    fn every_truncation_of_a_progressive_jpeg_is_refused() {
        for (name, bytes) in PROGRESSIVE {
            for keep in 0..bytes.len() {
                assert!(check_jpeg_complete(&bytes[..keep]).is_err(), "{name} cut to {keep} bytes");
            }
        }
    }

    /// 16 of 363 cuts pass.
    #[test]
    fn dc_first_scans_with_bytes_missing_are_refused() {
        assert_refused(&PROGRESSIVE, |pass| pass == Pass::DcFirst, 8);
    }

    /// A bit a block, any bit: only the data's length tells, which a cut of a stuffed byte's
    /// 0xFF (leaving its 0x00 as a byte of data) keeps: 1 of 80 cuts passes.
    #[test]
    fn dc_refinement_scans_with_bytes_missing_are_refused() {
        assert_refused(&PROGRESSIVE, |pass| pass == Pass::DcRefine, 2);
    }

    /// 179 of 2590 cuts pass.
    #[test]
    fn ac_first_scans_with_bytes_missing_are_refused() {
        assert_refused(&PROGRESSIVE, |pass| pass == Pass::AcFirst, 10);
    }

    /// 1006 of 3712 cuts pass: refinement scans are mostly raw correction bits, which any
    /// value fits, and their codes fall back into step with the blocks within a few blocks
    /// of the cut. The damage those leave is in the low bits of those few blocks (0.4 levels
    /// of 255 on average over the picture, at worst 71 in a pixel).
    #[test]
    fn ac_refinement_scans_with_bytes_missing_are_refused() {
        assert_refused(&PROGRESSIVE, |pass| pass == Pass::AcRefine, 30);
    }

    /// Every scan of the file with restart markers (198 of 2468 cuts pass), and each of its
    /// markers taken out.
    #[test]
    fn progressive_scans_with_restart_markers_and_bytes_missing_are_refused() {
        assert_refused(&PROGRESSIVE[2..], |_| true, 10);
        let bytes = PROGRESSIVE[2].1;
        for (_, data) in scans(bytes) {
            for at in data.filter(|&at| bytes[at] == 0xFF && (0xD0..=0xD7).contains(&bytes[at + 1])) {
                let cut = [&bytes[..at], &bytes[at + 2..]].concat();
                assert!(check_jpeg_complete(&cut).is_err(), "restart marker at {at} taken out");
            }
        }
    }

    /// The 4:2:0 file's luma is 7 × 5 blocks, its MCUs' 8 × 6: a scan of it alone that ran
    /// over the MCUs' blocks would end early; its chroma's AC scans are over 4 × 3 blocks.
    #[test]
    fn a_component_alone_is_decoded_over_its_own_blocks() {
        let mut tables = Tables::default();
        let bytes = PROGRESSIVE[1].1;
        let sof = bytes.windows(2).position(|w| w == [0xFF, 0xC2]).unwrap();
        tables.read(0xC2, &bytes[sof + 4..]).unwrap();
        let frame = tables.frame.as_ref().unwrap();
        assert_eq!((frame.width, frame.height), (54, 38));
        assert_eq!(frame.blocks((2, 2)), (7, 5));
        assert_eq!(frame.blocks((1, 1)), (4, 3));
        check_jpeg_complete(bytes).unwrap();
    }
}
