// Minimal OpenEXR reader for prefilter's table files (docs/export.md, "Tables"): single-part,
// scanline, NO_COMPRESSION, 32-bit FLOAT channels named R, G, B, A. Anything else throws an Error
// that says what was found. Rows are returned in file order (EXR row 0 = texture row 0, no flip).

const MAGIC = 20000630;
const PIXEL_TYPES = ['UINT', 'HALF', 'FLOAT'];
const COMPRESSIONS = ['NO', 'RLE', 'ZIPS', 'ZIP', 'PIZ', 'PXR24', 'B44', 'B44A', 'DWAA', 'DWAB'];
const ORDER = ['R', 'G', 'B', 'A'];

class Reader {
  constructor(buffer) {
    this.view = new DataView(buffer);
    this.bytes = new Uint8Array(buffer);
    this.pos = 0;
  }
  need(n) {
    if (this.pos + n > this.bytes.length) throw new Error('EXR: file is truncated');
  }
  string() {
    const start = this.pos;
    while (this.pos < this.bytes.length && this.bytes[this.pos] !== 0) this.pos++;
    this.need(1);
    const text = String.fromCharCode(...this.bytes.subarray(start, this.pos));
    this.pos++;
    return text;
  }
  int32() { this.need(4); const v = this.view.getInt32(this.pos, true); this.pos += 4; return v; }
  uint8() { this.need(1); return this.bytes[this.pos++]; }
  uint64() {
    this.need(8);
    const lo = this.view.getUint32(this.pos, true);
    const hi = this.view.getUint32(this.pos + 4, true);
    this.pos += 8;
    return hi * 4294967296 + lo;
  }
}

function parseChannels(r, end) {
  const channels = [];
  for (;;) {
    const name = r.string();
    if (name === '') break;
    const pixelType = r.int32();
    r.pos += 4; // pLinear + 3 reserved bytes
    const xSampling = r.int32();
    const ySampling = r.int32();
    channels.push({ name, pixelType, xSampling, ySampling });
  }
  if (r.pos !== end) throw new Error('EXR: malformed channel list');
  return channels;
}

function parseHeader(r) {
  const header = {};
  for (;;) {
    const name = r.string();
    if (name === '') return header;
    const type = r.string();
    const size = r.int32();
    const end = r.pos + size;
    r.need(size);
    if (name === 'channels' && type === 'chlist') header.channels = parseChannels(r, end);
    else if (name === 'compression') header.compression = r.uint8();
    else if (name === 'dataWindow' && type === 'box2i') {
      header.dataWindow = { xMin: r.int32(), yMin: r.int32(), xMax: r.int32(), yMax: r.int32() };
    } else if (name === 'type') header.partType = r.string();
    r.pos = end;
  }
}

/**
 * Decode an uncompressed float32 scanline EXR.
 * @param {ArrayBuffer} arrayBuffer
 * @returns {{width: number, height: number, channels: string[], data: Float32Array}}
 *   data is interleaved in R, G, B, A order (only the channels present), top row of the file first.
 */
export function decodeExr(arrayBuffer) {
  const r = new Reader(arrayBuffer);
  if (r.int32() !== MAGIC) throw new Error('EXR: not an OpenEXR file (bad magic number)');
  const version = r.int32();
  if (version & 0x200) throw new Error('EXR: tiled files are not supported (scanline only)');
  if (version & 0x800) throw new Error('EXR: deep data is not supported');
  if (version & 0x1000) throw new Error('EXR: multi-part files are not supported');
  const header = parseHeader(r);
  const { channels, compression, dataWindow } = header;
  if (!channels || compression === undefined || !dataWindow) {
    throw new Error('EXR: header lacks channels, compression or dataWindow');
  }
  if (compression !== 0) {
    throw new Error(`EXR: compression ${COMPRESSIONS[compression] ?? compression} is not supported (NO_COMPRESSION only)`);
  }
  if (header.partType && header.partType !== 'scanlineimage') {
    throw new Error(`EXR: part type ${header.partType} is not supported (scanlineimage only)`);
  }
  for (const c of channels) {
    if (c.pixelType !== 2) {
      throw new Error(`EXR: channel ${c.name} has ${PIXEL_TYPES[c.pixelType] ?? c.pixelType} pixels (FLOAT only)`);
    }
    if (c.xSampling !== 1 || c.ySampling !== 1) throw new Error(`EXR: channel ${c.name} is subsampled`);
    if (!ORDER.includes(c.name)) throw new Error(`EXR: channel ${c.name} is not one of R, G, B, A`);
  }
  const width = dataWindow.xMax - dataWindow.xMin + 1;
  const height = dataWindow.yMax - dataWindow.yMin + 1;
  if (width <= 0 || height <= 0) throw new Error('EXR: empty data window');
  const names = ORDER.filter((n) => channels.some((c) => c.name === n));
  const n = names.length;
  const slot = channels.map((c) => names.indexOf(c.name)); // file channel -> output component
  const data = new Float32Array(width * height * n);
  const offsets = [];
  for (let y = 0; y < height; y++) offsets.push(r.uint64());
  const rowBytes = 4 * width * channels.length;
  for (const offset of offsets) {
    r.pos = offset;
    const y = r.int32() - dataWindow.yMin;
    const byteCount = r.int32();
    if (y < 0 || y >= height) throw new Error(`EXR: scanline ${y + dataWindow.yMin} outside the data window`);
    if (byteCount !== rowBytes) throw new Error(`EXR: scanline ${y} has ${byteCount} bytes, expected ${rowBytes}`);
    r.need(byteCount);
    let p = r.pos;
    for (let c = 0; c < channels.length; c++) {
      const k = slot[c];
      let o = y * width * n + k;
      for (let x = 0; x < width; x++, p += 4, o += n) data[o] = r.view.getFloat32(p, true);
    }
  }
  return { width, height, channels: names, data };
}
