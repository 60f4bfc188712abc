// .splatvq decoder for the splatconv player, run in a web worker (one per .splatvq segment).
//
// The page posts its source ({type: "init", source}), then the file's bytes as they
// arrive ({type: "bytes", data}) and then
// {type: "end"}; the worker answers {type: "header", count, cameras, blocks}, then
// one {type: "block", start, count, words, order, ms} per block, in file order (words:
// the block's .splatv texture records, 16 uint32 a splat, in payload order; order: their
// indices in the block in importance order, or null where that is payload order), then
// {type: "done"} -- or {type: "error", message} with a plain-language reason, and nothing more.
//
// Every byte is as specs/splatvq.md says (version 6), refused where
// splatconv/formats/splatvq.py and splatvq_codec.py refuse it, and the arithmetic is
// that of splatvq_codec.py's decode_block, operation for operation, in
// doubles (products with exact powers of two, one sum, one square root, one
// division), rounded to float32 (Math.fround) and then to a half by round to nearest
// even, saturating at +-65504: the words are Python's, bit for bit (tests check).
// Each block's records come out in payload order, with their importance order beside them
// (record_order in splatvq_codec.py: the order the viewer draws depth ties in, as in a
// .splatv, and the order decode_block gives them in): the page draws ties in it.
// Each block is a raw deflate stream, inflated by the browser's own
// DecompressionStream("deflate-raw"): native code, no decoder shipped in the page.
"use strict";

const MAGIC = "SPVQ";
const VERSION = 6;
const CODER_DEFLATE_RAW = 1;
const CHUNK_LOG2 = 8;
const CHUNK = 1 << CHUNK_LOG2;
const BLOCK = 1 << 16;
const PREAMBLE = 31;           // magic, version, coder, 12 setting bytes, chunk_log2, json_length, json_size,
                               // block_count
const ENTRY = 16;              // coded, raw, payload (inflated bytes), stored: four uint32
const MAX_JSON = 64 << 20;
const MAX_RATIO = 1032;        // deflate gives at most this many bytes a stored byte
const MAX_SPLATS = 65536 * 1024;
const CHUNK_BYTES = 32, RAW_BYTES = 64, WORDS = 16;
// The per-splat value columns of a payload, in order (SPLAT_FIELDS in splatvq_codec.py):
// name, values per splat, coding. BYTE: one plane. PLAIN: w byte planes, lowest first
// (w from the block's width table; none: every value 0). SATURATING: one plane of
// min(v, 255), then, for the splats whose byte is 255 (in plane order), v - 255 in w planes.
const BYTE = 0, PLAIN = 1, SATURATING = 2;
const SPLAT_FIELDS = [
  ["x_step", 1, SATURATING], ["yz", 2, PLAIN], ["window_index", 1, BYTE], ["rotation", 3, PLAIN],
  ["scale", 3, SATURATING], ["color", 4, BYTE], ["trbf_center", 1, PLAIN], ["trbf_scale", 1, SATURATING],
  ["motion", 9, SATURATING], ["omega", 4, SATURATING],
];
const MAX_WIDTH = 4, SATURATED = 255;
const sumFields = (bytes) => SPLAT_FIELDS.reduce((sum, [, count, coding]) => sum + count * bytes(coding), 0);
// One width byte for each plain or saturating column; the fewest and most bytes a coded splat takes.
const WIDTH_COLUMNS = sumFields((coding) => (coding === BYTE ? 0 : 1));
const SPLAT_BYTES_MIN = sumFields((coding) => (coding === PLAIN ? 0 : 1));
const SPLAT_BYTES_MAX = sumFields((coding) => (coding === BYTE ? 1 : MAX_WIDTH + (coding === SATURATING ? 1 : 0)));
// The class of a zigzag code u: how many of CLASS_LIMITS it reaches. Motion and omega
// planes after motion_0 are stored in the stable order of the splats by the class of
// the motion codes decoded before them (CLASSED_BY in splatvq_codec.py).
const CLASS_LIMITS = [8, 32, 128, 512];
const CLASS_TOP = CLASS_LIMITS[CLASS_LIMITS.length - 1], TOP_CLASS = CLASS_LIMITS.length;
const CLASS_OF = new Uint8Array(CLASS_TOP);  // the class of each code below the last limit
CLASS_LIMITS.forEach((limit) => { for (let u = limit; u < CLASS_TOP; u++) CLASS_OF[u]++; });
// window_index = level * 64 + (e + WINDOW_BIAS) * 4 + the dropped quaternion component: the
// splat's boost level (0-3), its window exponent e (-13..2) and rotation index.
const WINDOW_BIAS = 13;
const SCALE_ZERO = 0, SCALE_INF = 1, SCALE_FIRST = 2;
const HALF_INF = 0x7c00;
const POSITION_CODE_MAX = 4294967295;
// Preamble bytes 6..17: name, signed, lowest, highest (SETTING_LIMITS in splatvq_codec.py).
const SETTING = [
  ["position_shift", true, -30, 30], ["rotation_bits", false, 2, 16], ["scale_step", false, 1, 255],
  ["trbf_scale_step", false, 1, 255], ["time_shift", false, 0, 30], ["omega_shift", false, 0, 30],
  ["motion_shift", true, -30, 30], ["acceleration_shift", false, 0, 8], ["jerk_shift", false, 0, 8],
  ["alpha_levels", false, 0, 7], ["flat_octaves", false, 0, 15], ["boost_step", false, 0, 4],
];
// A splat's geometric steps are its boost level times boost_step bits finer; a rotation component
// takes at most 16 bits.
const ROTATION_BITS_MAX = 16;
const CHUNK_LOG2_AT = 6 + SETTING.length, JSON_AT = CHUNK_LOG2_AT + 1, JSON_SIZE_AT = JSON_AT + 4;
const BLOCKS_AT = JSON_SIZE_AT + 4;

// 2^x for integer x, exactly, past every exponent a file can give (halving and doubling 1
// are exact in doubles; below 2^-1074 it is 0 and above 2^1023 Infinity: what decodes
// from such a product is the same half as Python's ldexp gives).
const POW2_BIAS = 1100;
const POW2 = new Float64Array(2 * POW2_BIAS + 1);
POW2[POW2_BIAS] = 1;
for (let i = 1; i <= POW2_BIAS; i++) {
  POW2[POW2_BIAS + i] = POW2[POW2_BIAS + i - 1] * 2;
  POW2[POW2_BIAS - i] = POW2[POW2_BIAS - i + 1] / 2;
}

// float64 -> float32 (nearest even) -> half (nearest even; finite values past 65504
// saturate), as packing.float_to_half does on the float32 of the value.
const f32 = new Float32Array(1), u32 = new Uint32Array(f32.buffer);
function half(v) {
  f32[0] = v;
  const x = u32[0], a = x & 0x7fffffff;
  // A normal half (most values): drop 13 mantissa bits, ties to even (adding 0xfff and
  // the lowest kept bit carries exactly when the dropped bits round up; a carry moves the exponent).
  if (((a - 0x38800000) >>> 0) <= 0x477fe000 - 0x38800000) {
    return ((x >>> 16) & 0x8000) | ((a - 0x38000000 + 0xfff + ((a >>> 13) & 1)) >>> 13);
  }
  return halfOther(x);
}

// Infinity, NaN, past 65504, zero and subnormal halves.
function halfOther(x) {
  const sign = (x >>> 16) & 0x8000;
  const a = x & 0x7fffffff;
  if (a >= 0x7f800000) return sign | (a === 0x7f800000 ? HALF_INF : 0x7e00 | ((a >>> 13) & 0x3ff));
  if (a > 0x477fe000) return sign | 0x7bff;
  // Zero or a subnormal half: the value in steps of 2^-24, ties to even (exact in doubles).
  f32[0] = 0;
  u32[0] = a;
  const t = f32[0] * 16777216;
  let f = Math.floor(t);
  const d = t - f;
  if (d > 0.5 || (d === 0.5 && (f & 1))) f++;
  return sign | f;
}

class Refusal extends Error {}

// ------------------------------------------------------------------ streaming input

let pieces = [], available = 0, ended = false, failed = false, finished = false;

function take(n) {
  // Exactly n bytes off the front of what arrived (n <= available).
  if (pieces.length && pieces[0].length >= n) {
    const out = pieces[0].subarray(0, n);
    pieces[0] = pieces[0].subarray(n);
    if (!pieces[0].length) pieces.shift();
    available -= n;
    return out;
  }
  const out = new Uint8Array(n);
  let at = 0;
  while (at < n) {
    const p = pieces[0], k = Math.min(p.length, n - at);
    out.set(p.subarray(0, k), at);
    at += k;
    if (k === p.length) pieces.shift(); else pieces[0] = p.subarray(k);
  }
  available -= n;
  return out;
}

const file = {stage: "preamble", setting: null, jsonLength: 0, jsonSize: 0, blockCount: 0, blocks: [], next: 0,
              start: 0};
// Blocks' results are posted in file order: each waits for the one before it.
let posted = Promise.resolve();

// Read what can be read. Blocks are handed to the helper workers (or decoded here,
// one after another) as soon as their bytes are in; nothing here waits for them.
function advance() {
  if (failed || finished) return;
  try {
    for (;;) {
      if (file.stage === "preamble") {
        if (available < PREAMBLE) break;
        readPreamble(take(PREAMBLE));
      } else if (file.stage === "json") {
        if (available < file.jsonLength) break;
        // The header is raw deflate: read on once it is inflated (the bytes after it wait).
        file.stage = "inflating";
        inflate(take(file.jsonLength), file.jsonSize, "its header").then((text) => {
          file.meta = readJson(text);
          file.stage = "table";
          advance();
        }).catch((e) => fail(e instanceof Refusal ? e.message
                                                  : `the decoder failed (${e && e.message ? e.message : e}).`));
        break;
      } else if (file.stage === "inflating") {
        break;
      } else if (file.stage === "table") {
        if (available < file.blockCount * ENTRY) break;
        readTable(take(file.blockCount * ENTRY));
      } else if (file.stage === "blocks") {
        if (file.next === file.blocks.length) { file.stage = "after"; continue; }
        const block = file.blocks[file.next];
        if (available < block.stored) break;
        schedule(block, take(block.stored), file.next);
        file.next++;
      } else { // "after": the file must end where its last block does
        if (available) {
          throw new Refusal("the file is damaged: it has bytes after its last block (its block table " +
                            "does not describe it).");
        }
        break;
      }
    }
  } catch (e) {
    fail(e instanceof Refusal ? e.message : `the decoder failed (${e && e.message ? e.message : e}).`);
    return;
  }
  if (ended && file.stage !== "inflating") {
    finished = true;
    const complete = file.stage === "after";
    const reason = complete ? null : truncated();
    // The blocks that arrived are shown first; then the file is done, or said to be short.
    posted = posted.then(() => {
      if (failed) return;
      if (complete) self.postMessage({type: "done"});
      else fail(reason);
    });
  }
}

// ------------------------------------------------------------------ helpers: blocks decoded in parallel

let source = null, helpers = null, jobs = new Map(), jobId = 0, waiting = [];
// A helper is given a block when it has fewer than this many: the blocks go to whichever helper
// is free, not in turn. A helper's first blocks run slower (its code is compiled as it runs, on
// a machine whose cores are busy), and one that was dealt every other block kept the other
// waiting at the end: on two cores, a tenth of the decode.
const MAX_HELPERS = 4, IN_FLIGHT = 1;

function startHelpers(blocks) {
  const cores = (self.navigator && self.navigator.hardwareConcurrency) || 1;
  const count = Math.min(MAX_HELPERS, cores, blocks);
  if (count < 2 || !source || typeof Worker === "undefined") return;
  try {
    const url = URL.createObjectURL(new Blob([source], {type: "text/javascript"}));
    helpers = [];
    for (let i = 0; i < count; i++) {
      const helper = new Worker(url);
      helper.busy = 0;
      helper.onmessage = (event) => {
        const msg = event.data, job = jobs.get(msg.id);
        jobs.delete(msg.id);
        helper.busy--;
        dispatch();
        if (msg.error !== undefined) job.reject(new Refusal(msg.error));
        else job.resolve({words: msg.words, order: msg.order, ms: msg.ms, inflateMs: msg.inflateMs});
      };
      helper.onerror = (event) => {
        event.preventDefault();
        fail(`the decoder failed (${event.message}).`);
      };
      helper.postMessage({type: "helper"});
      helpers.push(helper);
    }
  } catch (e) {
    helpers = null; // no nested workers here: decode in this worker
  }
}

function dispatch() {
  while (waiting.length && !failed) {
    const helper = helpers.reduce((a, h) => (h.busy < a.busy ? h : a));
    if (helper.busy >= IN_FLIGHT) return;
    helper.busy++;
    const job = waiting.shift();
    helper.postMessage(job, [job.stored.buffer]);
  }
}

function schedule(block, stored, i) {
  const which = `block ${i + 1} of ${file.blocks.length}`;
  let result;
  if (helpers) {
    const id = ++jobId;
    const own = stored.byteOffset === 0 && stored.byteLength === stored.buffer.byteLength ? stored : stored.slice();
    result = new Promise((resolve, reject) => jobs.set(id, {resolve, reject}));
    waiting.push({type: "decode", id, stored: own, coded: block.coded, raw: block.raw, payload: block.payload,
                  setting: file.setting, which});
    dispatch();
    result.catch(() => {}); // reported in order below
  }
  posted = posted.then(async () => {
    if (failed) return;
    try {
      const {words, order, ms, inflateMs} = await (result || decodeBlock(stored, block.coded, block.raw,
                                                                        block.payload, file.setting, which));
      if (failed) return;
      self.postMessage({type: "block", start: block.start, count: block.coded + block.raw, words, order, ms,
                        inflateMs}, order ? [words.buffer, order.buffer] : [words.buffer]);
    } catch (e) {
      fail(e instanceof Refusal ? e.message : `the decoder failed (${e && e.message ? e.message : e}).`);
    }
  });
}

function truncated() {
  if (file.stage === "blocks") {
    return `the file is truncated: it ends inside block ${file.next + 1} of ${file.blocks.length} ` +
           "(an interrupted download or copy?); the splats before it are shown.";
  }
  return "the file is truncated: it ends inside its header (an interrupted download or copy?).";
}

function fail(message) {
  if (failed) return;
  failed = true;
  pieces = [];
  available = 0;
  waiting = [];
  if (helpers) helpers.forEach((h) => h.terminate());
  self.postMessage({type: "error", message});
}

// ------------------------------------------------------------------ header and block table

function readPreamble(bytes) {
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (String.fromCharCode(bytes[0], bytes[1], bytes[2], bytes[3]) !== MAGIC) {
    throw new Refusal("this is not a .splatvq file (it does not start with SPVQ).");
  }
  if (bytes[4] !== VERSION) {
    throw new Refusal(`it is a .splatvq file of version ${bytes[4]}; this page reads version ${VERSION}.`);
  }
  if (bytes[5] !== CODER_DEFLATE_RAW) {
    throw new Refusal(`its blocks use coder ${bytes[5]}, which this page does not know (it knows 1, raw deflate).`);
  }
  const setting = {};
  SETTING.forEach(([name, signed, lo, hi], i) => {
    const v = signed ? dv.getInt8(6 + i) : dv.getUint8(6 + i);
    if (v < lo || v > hi) throw new Refusal(`its header is damaged (setting ${name} is ${v}, outside ${lo}..${hi}).`);
    setting[name] = v;
  });
  if (bytes[CHUNK_LOG2_AT] !== CHUNK_LOG2) {
    throw new Refusal(`its header is damaged (chunks of 2^${bytes[CHUNK_LOG2_AT]} splats, not 2^8).`);
  }
  file.setting = setting;
  file.jsonLength = dv.getUint32(JSON_AT, true);
  file.jsonSize = dv.getUint32(JSON_SIZE_AT, true);
  file.blockCount = dv.getUint32(BLOCKS_AT, true);
  if (file.jsonSize > MAX_JSON || file.jsonLength > MAX_JSON) {
    throw new Refusal(`its header is damaged (it claims a header of ${Math.max(file.jsonSize, file.jsonLength)} ` +
                      "bytes).");
  }
  if (file.jsonSize > MAX_RATIO * file.jsonLength + 64) {
    throw new Refusal(`its header is damaged (it claims ${file.jsonSize} bytes of header from ` +
                      `${file.jsonLength} stored, more than deflate can give).`);
  }
  if (file.blockCount > MAX_SPLATS) {
    throw new Refusal(`its block table is damaged (it claims ${file.blockCount} blocks).`);
  }
  file.stage = "json";
}

function readJson(bytes) {
  let meta;
  try {
    meta = JSON.parse(new TextDecoder("utf-8", {fatal: true}).decode(bytes));
  } catch (e) {
    throw new Refusal("its header is damaged (not valid JSON).");
  }
  if (!meta || typeof meta !== "object" || Array.isArray(meta)) {
    throw new Refusal("its header is damaged (not a JSON object).");
  }
  return meta;
}

function readTable(bytes) {
  const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let total = 0;
  for (let i = 0; i < file.blockCount; i++) {
    const coded = dv.getUint32(ENTRY * i, true), raw = dv.getUint32(ENTRY * i + 4, true);
    const payload = dv.getUint32(ENTRY * i + 8, true), stored = dv.getUint32(ENTRY * i + 12, true);
    const n = coded + raw;
    if (n === 0 || n > BLOCK) {
      throw new Refusal(`its block table is damaged (block ${i + 1} claims ${n} splats; a block holds 1 to ${BLOCK}).`);
    }
    // As payload_bounds: the chunk tables, the width table and the raw records, and each coded splat's bytes.
    const fixed = Math.ceil(coded / CHUNK) * CHUNK_BYTES + WIDTH_COLUMNS + raw * RAW_BYTES;
    const fewest = fixed + coded * SPLAT_BYTES_MIN, most = fixed + coded * SPLAT_BYTES_MAX;
    if (payload < fewest || payload > most) {
      throw new Refusal(`its block table is damaged (block ${i + 1} claims ${payload} decoded bytes, but its ` +
                        `${n} splats take ${fewest} to ${most}).`);
    }
    if (payload > MAX_RATIO * stored + 64) {
      throw new Refusal(`its block table is damaged (block ${i + 1} claims ${payload} decoded bytes from ` +
                        `${stored} stored, more than deflate can give).`);
    }
    file.blocks.push({coded, raw, payload, stored, start: total});
    total += n;
  }
  const count = file.meta.count;
  if (count !== total) {
    throw new Refusal(`its header is damaged (its count ${String(count).slice(0, 40)} is not the ${total} ` +
                      "splats its block table lists).");
  }
  if (total === 0) throw new Refusal("it holds no splats.");
  if (total > MAX_SPLATS) throw new Refusal(`it holds ${total} splats, more than a .splatv texture takes.`);
  startHelpers(file.blockCount);
  self.postMessage({type: "header", count: total, blocks: file.blockCount,
                    cameras: Array.isArray(file.meta.cameras) ? file.meta.cameras : [],
                    setting: typeof file.meta.setting === "string" ? file.meta.setting : null});
  file.stage = "blocks";
}

// ------------------------------------------------------------------ one block

// The output is read into a buffer of the declared size and the stream cancelled as
// soon as it gives more: a block of deflated zeros that declares a small payload
// costs no more memory than it declares.
async function inflate(stored, expected, which) {
  const out = new Uint8Array(expected);
  let got = 0;
  try {
    // Written straight into the stream: a Blob's stream would go through the browser's blob store.
    const inflater = new DecompressionStream("deflate-raw");
    const writer = inflater.writable.getWriter();
    writer.write(stored).catch(() => {}); // a corrupt stream fails the read below
    writer.close().catch(() => {});
    const reader = inflater.readable.getReader();
    for (;;) {
      const {done, value} = await reader.read();
      if (done) break;
      if (got + value.length > expected) {
        reader.cancel().catch(() => {});
        got = expected + 1;
        break;
      }
      out.set(value, got);
      got += value.length;
    }
  } catch (e) {
    throw new Refusal(`${which} is corrupt: its compressed data cannot be decoded.`);
  }
  if (got > expected) {
    throw new Refusal(`${which} is damaged: it decodes to more than the ${expected} bytes declared for it.`);
  }
  if (got !== expected) {
    throw new Refusal(`${which} is damaged: it decodes to ${got} bytes, not the ${expected} declared for it.`);
  }
  return out;
}

async function decodeBlock(stored, coded, raw, size, setting, which) {
  const t0 = performance.now();
  const payload = await inflate(stored, size, which);
  const t1 = performance.now();
  const {words, order} = decodePayload(payload, coded, raw, setting, which);
  return {words, order, ms: performance.now() - t0, inflateMs: t1 - t0};
}

// A zigzag code -> its integer: 0, -1, 1, -2, ... Codes may pass 2^32 (a saturating
// column's byte 255 plus a 32-bit escape): those in doubles (exact below 2^53).
function unzigzag(u) {
  if (u < 0x80000000) return (u >>> 1) ^ -(u & 1);
  return u & 1 ? -(u + 1) / 2 : u / 2;
}

// Where a payload's value columns lie, as unpack_payload reads them, checked against
// the payload's length: for each column (SPLAT_FIELDS order) its first
// plane, its width and, for a saturating one, how many escapes it has and where.
function layout(p, n, raw, which) {
  const short = () => new Refusal(`${which} is damaged (its data ends before its last splat).`);
  let at = Math.ceil(n / CHUNK) * CHUNK_BYTES;
  if (at + WIDTH_COLUMNS > p.length) throw short();
  const widths = p.subarray(at, at + WIDTH_COLUMNS);
  const widest = Math.max(...widths);
  if (widest > MAX_WIDTH) {
    throw new Refusal(`${which} is damaged (a column of its values is ${widest} bytes wide; at most ${MAX_WIDTH}).`);
  }
  at += WIDTH_COLUMNS;
  const columns = {};
  let w = 0;
  for (const [name, count, coding] of SPLAT_FIELDS) {
    const list = columns[name] = [];
    for (let j = 0; j < count; j++) {
      const column = {at, width: coding === BYTE ? 1 : widths[w++], escapes: 0, escapesAt: 0};
      if (coding === SATURATING) {
        // Its escapes are counted only where they take bytes (with a width of 0 each is 255).
        if (at + n > p.length) throw short();
        column.escapes = column.width ? countSaturated(p.subarray(at, at + n)) : 0;
        column.escapesAt = at + n;
        at += n + column.width * column.escapes;
      } else {
        at += column.width * n;
      }
      if (at > p.length) throw short();
      list.push(column);
    }
  }
  const rawAt = at;
  at += raw * RAW_BYTES;
  if (at > p.length) throw short();
  if (at !== p.length) throw new Refusal(`${which} is damaged (it has ${p.length - at} bytes after its last splat).`);
  return {columns, rawAt};
}

// How many bytes of a plane are 255 (few are: the native search runs past the rest).
function countSaturated(plane) {
  let m = 0;
  for (let t = plane.indexOf(SATURATED); t !== -1; t = plane.indexOf(SATURATED, t + 1)) m++;
  return m;
}

// A plain column's values, in splat order, into `out` (a Uint32Array of n): byte plane
// after byte plane.
function plainValues(p, n, column, out) {
  const {at, width} = column;
  if (width === 0) return out.fill(0, 0, n);
  out.set(p.subarray(at, at + n));
  for (let b = 1; b < width; b++) orPlane(out, p, at + b * n, 8 * b, n);
  return out;
}

function orPlane(out, p, plane, shift, n) {
  for (let i = 0; i < n; i++) out[i] |= p[plane + i] << shift;
}

// The x-th escaped value of a saturating column: 255 plus its escape's bytes (lowest first,
// a plane of as many bytes as the column has escapes each).
function escaped(p, column, x) {
  let v = SATURATED;
  for (let b = 0, at = column.escapesAt + x; b < column.width; b++, at += column.escapes) {
    v += p[at] * POW2[POW2_BIAS + 8 * b];
  }
  return v;
}

// A saturating column's values, in its plane's order, into `out` (a Float64Array of n:
// a value may pass 2^32).
function saturatingValues(p, n, column, out) {
  const plane = p.subarray(column.at, column.at + n);
  out.set(plane);
  if (column.width === 0) return out; // every escape is 255 itself
  for (let t = plane.indexOf(SATURATED), x = 0; t !== -1; t = plane.indexOf(SATURATED, t + 1)) {
    out[t] = escaped(p, column, x++);
  }
  return out;
}

// Where each splat's value lies in a classed plane: the splats in the stable order of
// their classes (a counting sort: numpy's stable argsort of the classes, inverted).
// Each hot loop is a function of its own, with one loop: V8 compiles a long loop while
// it runs (on-stack replacement), and code after a loop that has not run yet has no type
// feedback, so a function of several loops was compiled and dropped again several times
// a block, for each worker's first blocks (most of the decode's time on two cores).
function classRanks(cls, n, rank) {
  const next = new Int32Array(CLASS_LIMITS.length + 1);
  countClasses(cls, n, next);
  for (let c = 0, sum = 0; c < next.length; c++) {
    const count = next[c];
    next[c] = sum;
    sum += count;
  }
  assignRanks(cls, n, next, rank);
  return rank;
}

function countClasses(cls, n, next) {
  for (let i = 0; i < n; i++) next[cls[i]]++;
}

function assignRanks(cls, n, next, rank) {
  for (let i = 0; i < n; i++) rank[i] = next[cls[i]]++;
}

// Working arrays of at least n elements, kept from block to block (a worker decodes one block
// at a time), so that a block allocates little beyond what it hands back: each splat's step
// exponent k, window exponent e and alpha coarsening c; a column's values, a few columns at a
// time (plain: the rotation's three together); the motion classes and ranks; the importance
// sort's keys. Some 4.5 MB a worker for a block of 65,536 splats.
let scratch = null;
function workspace(n) {
  if (!scratch || scratch.size < n) {
    scratch = {
      size: n, k: new Int32Array(n), e: new Int32Array(n), c: new Int32Array(n), boost: new Int32Array(n),
      plain: [new Uint32Array(n), new Uint32Array(n), new Uint32Array(n)], values: new Float64Array(n),
      values1: new Float64Array(n), values2: new Float64Array(n), values3: new Float64Array(n),
      cls: new Uint8Array(n), rank: new Int32Array(n), keys: new Float64Array(n), low: new Uint32Array(n),
      high: new Uint32Array(n), count: new Uint32Array(DIGITS * RADIX),
    };
  }
  return scratch;
}

// A block payload -> its records. Field by field over all splats (short loops over
// contiguous byte planes run several times faster than one loop doing everything),
// a function a field (each gets its own type feedback, so that the first blocks a
// worker decodes are not slowed by one large function optimized and dropped again).
// Refusals come in the order decode_block makes them.
function decodePayload(p, n, raw, s, which) {
  const {columns, rawAt} = layout(p, n, raw, which);
  const out = new Uint32Array((n + raw) * WORDS);
  new Uint8Array(out.buffer, n * WORDS * 4).set(p.subarray(rawAt, rawAt + raw * RAW_BYTES));
  if (!n) return {words: out, order: importanceOrder(out, raw)};
  const chunks = Math.ceil(n / CHUNK);
  const posBase = new Float64Array(p.buffer, p.byteOffset, 3 * chunks);
  for (let j = 0; j < 3 * chunks; j++) {
    if (!Number.isFinite(posBase[j])) throw new Refusal(`${which} is damaged (a chunk's position base is not finite).`);
  }
  const b = {
    p, n, s, which, columns, posBase,
    scaleBase: new Uint16Array(p.buffer, p.byteOffset + 24 * chunks, 3 * chunks),
    trbfBase: new Uint16Array(p.buffer, p.byteOffset + 30 * chunks, chunks),
    floats: new Float32Array(out.buffer, 0, n * WORDS),
    halves: new Uint16Array(out.buffer, 0, n * WORDS * 2),
    ...workspace(n),
  };
  scalesAndSteps(b);
  positions(b);
  windowExponents(b);
  rotations(b);
  scaleField(b, columns.trbf_scale[0], 31, b.trbfBase, 1, 0, s.trbf_scale_step);
  // Colour and opacity (word 7): the four bytes as they are.
  colourWords(out, p, columns.color[0].at, columns.color[1].at, columns.color[2].at, columns.color[3].at, n);
  motionAndOmega(b);
  temporalCentres(b);
  return {words: out, order: importanceOrder(out, n + raw)};
}

function colourWords(words, p, r, g, b, a, n) {
  for (let i = 0; i < n; i++) words[WORDS * i + 7] = (p[r + i] | (p[g + i] << 8) | (p[b + i] << 16) | (p[a + i] << 24)) >>> 0;
}

// ------------------------------------------------------------------ importance order

// The value of a half (exact in a double). Worked out where it is needed: a table of all
// 65,536 took some 10 ms to fill in each worker as it started, before its first block.
function halfValue(h) {
  const e = (h >> 10) & 0x1f, m = h & 0x3ff;
  const v = e === 0x1f ? (m ? NaN : Infinity) : (e === 0 ? m : m + 1024) * POW2[POW2_BIAS + Math.max(e, 1) - 25];
  return h & 0x8000 ? -v : v;
}
const DIGIT_BITS = 13, DIGITS = 4, RADIX = 1 << DIGIT_BITS, DIGIT = RADIX - 1;

// A block's importance order, as record_order in splatvq_codec.py: the records' indices,
// most important first, or null where that is their payload order. The records themselves
// stay where they are (moving 64 bytes a record cost a tenth of the decode): the page draws
// depth ties in this order instead (sort_worker.js). The key is the product of the three
// scale halves' values and the alpha byte (exact in doubles: the same bits as numpy's),
// records sorted stably by a 64-bit code of it that ascends as the key descends
// (0x7fffffffffffffff - bits for a key of 0 or more, -0 as +0; the bits of a negative
// key; all ones for NaN). An exact key has at most 41 significant bits, so the code's low
// 12 bits follow from its sign: the sort takes bits 12..63, in two 26-bit halves, with an
// LSD radix sort of four 13-bit digits (a digit all records share is skipped), all four
// counts made in one pass.
function importanceOrder(words, n) {
  const {keys, low, high, count} = workspace(n);
  count.fill(0);
  importanceKeys(new Uint16Array(words.buffer, words.byteOffset, n * WORDS * 2), words, keys, n);
  sortCodes(keys, new Uint32Array(keys.buffer), low, high, count, n);
  let order = null, spare = new Uint32Array(n);
  for (let d = 0; d < DIGITS; d++) {
    const at = d * RADIX, code = d < 2 ? low : high, shift = d & 1 ? DIGIT_BITS : 0;
    if (count[at + ((code[0] >>> shift) & DIGIT)] === n) continue; // one digit: the order stands
    offsets(count, at);
    if (order === null) {
      scatterFirst(code, shift, count, at, spare, n);
      order = new Uint32Array(n);
    } else {
      scatter(order, code, shift, count, at, spare, n);
    }
    [order, spare] = [spare, order];
  }
  return order;
}

// Where all three scales are normal halves (nearly always), the key is the product of their
// 11-bit integer significands, the alpha and one power of two: exact, so the same number as the
// product of the values.
function importanceKeys(halves, words, keys, n) {
  for (let i = 0; i < n; i++) {
    const h0 = halves[32 * i + 10], h1 = halves[32 * i + 11], h2 = halves[32 * i + 12];
    const e0 = (h0 >> 10) & 0x1f, e1 = (h1 >> 10) & 0x1f, e2 = (h2 >> 10) & 0x1f, alpha = words[WORDS * i + 7] >>> 24;
    let key;
    if (((e0 - 1) >>> 0) < 30 && ((e1 - 1) >>> 0) < 30 && ((e2 - 1) >>> 0) < 30) {
      key = ((h0 & 0x3ff) + 1024) * ((h1 & 0x3ff) + 1024) * ((h2 & 0x3ff) + 1024) * alpha *
            POW2[POW2_BIAS + e0 + e1 + e2 - 75];
      if ((h0 ^ h1 ^ h2) & 0x8000) key = -key;
    } else {
      key = halfValue(h0) * halfValue(h1) * halfValue(h2) * alpha;
    }
    keys[i] = key === 0 ? 0 : key;
  }
}

// Each key's two 26-bit halves of its code, and the counts of all four digits.
function sortCodes(keys, bits, low, high, count, n) {
  for (let i = 0; i < n; i++) {
    let lo = bits[2 * i], hi = bits[2 * i + 1];
    if (keys[i] !== keys[i]) {
      lo = hi = 0xffffffff;
    } else if (hi < 0x80000000) {
      lo = 0xffffffff - lo;
      hi = 0x7fffffff - hi;
    }
    const a = ((lo >>> 12) | (hi << 20)) & 0x3ffffff, b = hi >>> 6;
    low[i] = a;
    high[i] = b;
    count[a & DIGIT]++;
    count[RADIX + (a >>> DIGIT_BITS)]++;
    count[2 * RADIX + (b & DIGIT)]++;
    count[3 * RADIX + (b >>> DIGIT_BITS)]++;
  }
}

// A digit's counts -> where its records start.
function offsets(count, at) {
  for (let k = at, sum = 0; k < at + RADIX; k++) {
    const c = count[k];
    count[k] = sum;
    sum += c;
  }
}

function scatterFirst(code, shift, count, at, spare, n) {
  for (let i = 0; i < n; i++) spare[count[at + ((code[i] >>> shift) & DIGIT)]++] = i;
}

function scatter(order, code, shift, count, at, spare, n) {
  for (let i = 0; i < n; i++) {
    const r = order[i];
    spare[count[at + ((code[r] >>> shift) & DIGIT)]++] = r;
  }
}

// Scales (words 5-6, half slots 10-12) and the temporal scale (slot 31): integers only.
function scaleField(b, column, slot, base, stride, offset, step) {
  const {p, n, halves} = b, plane = column.at;
  for (let i = 0, x = 0; i < n; i++) {
    let u = p[plane + i];
    if (u === SATURATED) u = escaped(p, column, x++);
    let h;
    if (u === SCALE_ZERO) h = 0;
    else if (u === SCALE_INF) h = HALF_INF;
    else {
      h = (base[stride * (i >>> CHUNK_LOG2) + offset] + u - SCALE_FIRST) * step;
      if (h > HALF_INF) throw new Refusal(`${b.which} is damaged (a scale code decodes past the half range).`);
    }
    halves[32 * i + slot] = h;
  }
}

// Scales (words 5-6, half slots 10-12), each splat's coarsening c from its alpha byte
// (min(alpha_levels, 7 - floor(log2(max(alpha, 1))))), its boost (in bits) and its step
// exponent k (from its least scale, at most flat_octaves below its middle one, plus c,
// less the boost): the scales kept in registers.
function scalesAndSteps(b) {
  const {p, n, s, halves, k, c, boost, columns} = b;
  const v0 = saturatingValues(p, n, columns.scale[0], b.values);
  const v1 = saturatingValues(p, n, columns.scale[1], b.values1);
  const v2 = saturatingValues(p, n, columns.scale[2], b.values2);
  const coarsening = new Int32Array(256);
  for (let a = 0; a < 256; a++) coarsening[a] = Math.min(s.alpha_levels, 7 - (31 - Math.clz32(Math.max(1, a))));
  const bad = scaleSteps(halves, v0, v1, v2, b.scaleBase, s.scale_step, p, columns.color[3].at, coarsening,
                         s.flat_octaves << 10, s.position_shift, k, c, n);
  boosts(p, columns.window_index[0].at, s.boost_step, k, boost, n);
  if (bad) throw new Refusal(`${b.which} is damaged (a scale code decodes past the half range).`);
}

// A scale code -> its half: 0 and 1 are zero and infinity, the rest steps above the chunk's
// base; past infinity -1 (refused).
function scaleHalf(u, base, step) {
  if (u === SCALE_ZERO) return 0;
  if (u === SCALE_INF) return HALF_INF;
  const h = (base + u - SCALE_FIRST) * step;
  return h > HALF_INF ? -1 : h;
}

function scaleSteps(halves, v0, v1, v2, base, step, p, alphaPlane, coarsening, flat, shift, k, c, n) {
  let bad = false;
  for (let i = 0; i < n; i++) {
    const chunk = 3 * (i >>> CHUNK_LOG2);
    const s0 = scaleHalf(v0[i], base[chunk], step), s1 = scaleHalf(v1[i], base[chunk + 1], step);
    const s2 = scaleHalf(v2[i], base[chunk + 2], step);
    if ((s0 | s1 | s2) < 0) bad = true;
    halves[32 * i + 10] = s0;
    halves[32 * i + 11] = s1;
    halves[32 * i + 12] = s2;
    const middle = Math.max(Math.min(s0, s1), Math.min(Math.max(s0, s1), s2));
    const h = Math.max(Math.min(s0, s1, s2), middle - flat);
    const ci = coarsening[p[alphaPlane + i]];
    c[i] = ci;
    k[i] = Math.min(16, Math.max(-15, (h >> 10) - 15)) + shift + ci;
  }
  return bad;
}

// Each splat's boost in bits, its level (the window byte's top two bits) times boost_step, taken
// off its step exponent k.
function boosts(p, windowPlane, step, k, boost, n) {
  for (let i = 0; i < n; i++) {
    boost[i] = (p[windowPlane + i] >> 6) * step;
    k[i] -= boost[i];
  }
}

// Positions (words 0-2): f32(base + code * 2^k). Inside a chunk x is stored as the step
// from floor(previous code * 2^(previous k - k)), the chunk's first splat as its code.
function positions(b) {
  const {p, n, floats, posBase, k, columns} = b;
  positionX(b, saturatingValues(p, n, columns.x_step[0], b.values), floats, posBase, k, n);
  for (let j = 1; j < 3; j++) positionAxis(floats, posBase, plainValues(p, n, columns.yz[j - 1], b.plain[0]), k, j, n);
}

function positionX(b, steps, floats, posBase, k, n) {
  let previous = 0;
  for (let i = 0; i < n; i++) {
    let code = steps[i];
    if ((i & (CHUNK - 1)) !== 0) {
      const predicted = Math.floor(previous * POW2[POW2_BIAS + k[i - 1] - k[i]]);
      if (predicted > POSITION_CODE_MAX) throw new Refusal(`${b.which} is damaged (a position code past 2^32 - 1).`);
      code += predicted;
    }
    if (code > POSITION_CODE_MAX) throw new Refusal(`${b.which} is damaged (a position code past 2^32 - 1).`);
    previous = code;
    floats[16 * i] = posBase[3 * (i >>> CHUNK_LOG2)] + code * POW2[POW2_BIAS + k[i]];
  }
}

function positionAxis(floats, posBase, code, k, j, n) {
  for (let i = 0; i < n; i++) floats[16 * i + j] = posBase[3 * (i >>> CHUNK_LOG2) + j] + code[i] * POW2[POW2_BIAS + k[i]];
}

// Window exponent e, from the byte that also holds the boost level and the rotation index.
function windowExponents(b) {
  const {p, n, e} = b, plane = b.columns.window_index[0].at;
  for (let i = 0; i < n; i++) e[i] = ((p[plane + i] >> 2) & 15) - WINDOW_BIAS;
}

// Rotation (words 3-4, half slots 6-9): three kept components, the dropped one from them,
// rotation_bits plus the splat's boost (at most 16) each.
function rotations(b) {
  const {p, n, s, halves, columns, plain} = b, plane = columns.window_index[0].at;
  const r0 = plainValues(p, n, columns.rotation[0], plain[0]), r1 = plainValues(p, n, columns.rotation[1], plain[1]);
  const r2 = plainValues(p, n, columns.rotation[2], plain[2]);
  // Each boost level's tables: rotation_bits plus level * boost_step bits, at most 16.
  const byLevel = [0, 1, 2, 3].map((level) => {
    const bits = Math.min(ROTATION_BITS_MAX, s.rotation_bits + level * s.boost_step);
    return ROTATION_TABLES[bits] || rotationTables(bits);
  });
  for (let i = 0; i < n; i++) {
    const v = p[plane + i], index = v & 3;
    const {M, rotValue, rotHalf} = byLevel[v >> 6];
    const c0 = r0[i], c1 = r1[i], c2 = r2[i];
    if (c0 > M || c1 > M || c2 > M) throw new Refusal(`${b.which} is damaged (a rotation code past ${M}).`);
    const a0 = rotValue[c0], a1 = rotValue[c1], a2 = rotValue[c2];
    const q = 32 * i + 6;
    // The kept three fill the other slots in order.
    halves[q + (index === 0 ? 1 : 0)] = rotHalf[c0];
    halves[q + (index <= 1 ? 2 : 1)] = rotHalf[c1];
    halves[q + (index <= 2 ? 3 : 2)] = rotHalf[c2];
    halves[q + index] = half(Math.sqrt(Math.max(0, 1 - ((a0 * a0 + a1 * a1) + a2 * a2))));
  }
}

// A kept component depends on its code and bits alone: the value and half of every code of
// each number of bits, made once a worker.
const ROTATION_TABLES = [];
function rotationTables(bits) {
  const M = 2 ** bits - 1, rotValue = new Float64Array(M + 1), rotHalf = new Uint16Array(M + 1);
  for (let r = 0; r <= M; r++) {
    rotValue[r] = ((2 * r - M) / M) * Math.SQRT1_2;
    rotHalf[r] = half(rotValue[r]);
  }
  return (ROTATION_TABLES[bits] = {M, rotValue, rotHalf});
}

// Motion (words 8-12, half slots 16-24): degree d = 1, 2, 3 on the lattice
// 2^(k + motion_shift + (0, acceleration_shift, jerk_shift)[d - 1] - e d); omega (words
// 13-14, half slots 26-29) on the lattice 2^-(e + omega_shift - c). motion_0's plane is in
// splat order; motion_1's in the order of the class of motion_0, motion_2's of the larger
// of motion_0..1, every later one's and omega's of the largest of motion_0..2 (CLASSED_BY):
// cls holds each splat's class so far (the class of a maximum is the largest of the classes),
// rank where its value lies in the plane.
function motionAndOmega(b) {
  const {p, n, s, k, e, c, columns, values, values1, values2, values3, halves, cls, rank} = b;
  cls.fill(0, 0, n);
  identity(rank, n);
  const x = [0, s.acceleration_shift, s.jerk_shift].map((shift) => POW2_BIAS + s.motion_shift + shift);
  // motion_0..2 one at a time: each raises the classes the next plane is ordered by.
  for (let j = 0; j < 3; j++) {
    if (j >= 1) classRanks(cls, n, rank);
    // Every column's values as doubles (a saturating value may pass 2^32): one element type
    // for every call, so that each stays optimized.
    saturatingValues(p, n, columns.motion[j], values);
    termAndClass(halves, values, rank, 16 + j, x[0], k, e, cls, n);
  }
  classRanks(cls, n, rank);
  // The rest share that order: the three axes of a degree together, then omega's four.
  for (let d = 2; d <= 3; d++) {
    const first = 3 * (d - 1);
    saturatingValues(p, n, columns.motion[first], values);
    saturatingValues(p, n, columns.motion[first + 1], values1);
    saturatingValues(p, n, columns.motion[first + 2], values2);
    threeTerms(halves, values, values1, values2, rank, 16 + first, x[d - 1], k, e, d, n);
  }
  saturatingValues(p, n, columns.omega[0], values);
  saturatingValues(p, n, columns.omega[1], values1);
  saturatingValues(p, n, columns.omega[2], values2);
  saturatingValues(p, n, columns.omega[3], values3);
  omegaTerms(halves, values, values1, values2, values3, rank, POW2_BIAS - s.omega_shift, c, e, b.boost, n);
}

function identity(rank, n) {
  for (let i = 0; i < n; i++) rank[i] = i;
}

// Three motion columns of degree d into half slots slot..slot + 2: half(unzigzag(code) *
// 2^(x - POW2_BIAS + k[i] - d e[i])) for splat i, its codes at v0..v2[rank[i]].
function threeTerms(halves, v0, v1, v2, rank, slot, x, k, e, d, n) {
  for (let i = 0; i < n; i++) {
    const r = rank[i], step = POW2[x + k[i] - d * e[i]], q = 32 * i + slot;
    const a = v0[r], b = v1[r], c = v2[r];
    if (a !== 0) halves[q] = half(unzigzag(a) * step);
    if (b !== 0) halves[q + 1] = half(unzigzag(b) * step);
    if (c !== 0) halves[q + 2] = half(unzigzag(c) * step);
  }
}

// Omega's four columns into half slots 26..29, on the lattice 2^(x - POW2_BIAS + c[i] - e[i] - boost[i]).
function omegaTerms(halves, v0, v1, v2, v3, rank, x, c, e, boost, n) {
  for (let i = 0; i < n; i++) {
    const r = rank[i], step = POW2[x + c[i] - e[i] - boost[i]], q = 32 * i + 26;
    const a = v0[r], b = v1[r], f = v2[r], g = v3[r];
    if (a !== 0) halves[q] = half(unzigzag(a) * step);
    if (b !== 0) halves[q + 1] = half(unzigzag(b) * step);
    if (f !== 0) halves[q + 2] = half(unzigzag(f) * step);
    if (g !== 0) halves[q + 3] = half(unzigzag(g) * step);
  }
}

// One velocity column into half slot `slot`: half(unzigzag(code) * 2^(x - POW2_BIAS + k[i] - e[i]))
// for splat i, its code at values[rank[i]]; and each splat's class raised to its code's if larger.
function termAndClass(halves, values, rank, slot, x, k, e, cls, n) {
  for (let i = 0; i < n; i++) {
    const v = values[rank[i]];
    if (v !== 0) {
      halves[32 * i + slot] = half(unzigzag(v) * POW2[x + k[i] - e[i]]);
      const vc = v >= CLASS_TOP ? TOP_CLASS : CLASS_OF[v];
      if (vc > cls[i]) cls[i] = vc;
    }
  }
}

// Temporal centre (half slot 30) on the lattice 2^-(time_shift + boost).
function temporalCentres(b) {
  const {p, n, halves, boost} = b, x = POW2_BIAS - b.s.time_shift;
  const centre = plainValues(p, n, b.columns.trbf_center[0], b.plain[0]);
  for (let i = 0; i < n; i++) {
    const u = centre[i];
    if (u !== 0) halves[32 * i + 30] = half(unzigzag(u) * POW2[x - boost[i]]);
  }
}

// The page's worker gets {type: "init", source} (its own source, for helpers),
// then the file; a helper gets {type: "helper"}, then blocks to decode.
let helperMode = false, queue = Promise.resolve();
self.onmessage = (event) => {
  const msg = event.data;
  if (msg.type === "helper") {
    helperMode = true;
    return;
  }
  if (helperMode) {
    // One block at a time, so that each block's time is its own work.
    queue = queue.then(() => decodeBlock(msg.stored, msg.coded, msg.raw, msg.payload, msg.setting, msg.which)).then(
      ({words, order, ms, inflateMs}) => self.postMessage({id: msg.id, words, order, ms, inflateMs},
                                                          order ? [words.buffer, order.buffer] : [words.buffer]),
      (e) => self.postMessage({id: msg.id, error: e instanceof Refusal ? e.message
                                                  : `the decoder failed (${e && e.message ? e.message : e}).`}));
    return;
  }
  if (failed) return;
  if (msg.type === "init") {
    source = msg.source;
    return;
  }
  if (msg.type === "bytes") {
    const bytes = new Uint8Array(msg.data);
    if (bytes.length) { pieces.push(bytes); available += bytes.length; }
  } else if (msg.type === "end") {
    ended = true;
  }
  advance();
};
