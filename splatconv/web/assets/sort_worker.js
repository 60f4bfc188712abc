// Depth sort for the splatconv player, run in a web worker.
//
// The order is the one splaTV's viewer computes (and splatconv/render/sort.py
// reproduces for `splatconv render`): key = ToInt32((vp[2]*x + vp[6]*y + vp[10]*z) * 4096)
// in double precision from float32 positions, rescaled to 65,536 buckets by
// ToInt32((key - min) * 65536 / (max - min)), then a stable counting sort, nearest
// first. Splats that land in bucket 65,536 (the farthest) are dropped and the tail
// of the index list stays 0, as in the viewer, so both renderers blend the same list.
//
// Records are sorted in the order the viewer holds them, so that splats of one bucket
// are drawn in it: a .splatv's texture order, a .splatvq's importance order (the order
// splatconv's decoder gives its records in, with which a .splatv of it is written),
// while its texture holds each block's records as the block stores them. For such a
// segment the page sends each record's texture index beside its position (`order`),
// and the list holds texture indices: the records the viewer would draw, in its order
// (its tail, too, is the first record in that order).
"use strict";

const BUCKETS = 65536;
const positions = new Map(); // segment -> Float32Array of x, y, z per record, in the viewer's order
const textureIndex = new Map(); // segment -> Uint32Array: the texture record of each (absent: the same)
let counts = new Uint32Array(BUCKETS);
let keys = new Int32Array(0);

function depthOrder(pos, count, vp, map) {
  if (keys.length < count) keys = new Int32Array(count);
  const out = new Uint32Array(count);
  if (count === 0) return out;
  const a = vp[2], b = vp[6], c = vp[10];
  let lo = 2147483647, hi = -2147483648;
  for (let i = 0, j = 0; i < count; i++, j += 3) {
    const key = ((a * pos[j] + b * pos[j + 1] + c * pos[j + 2]) * 4096) | 0;
    keys[i] = key;
    if (key < lo) lo = key;
    if (key > hi) hi = key;
  }
  // hi == lo gives Infinity, and 0 * Infinity is NaN, whose ToInt32 is 0: one bucket.
  const inv = BUCKETS / (hi - lo);
  counts.fill(0);
  for (let i = 0; i < count; i++) {
    const bucket = ((keys[i] - lo) * inv) | 0;
    keys[i] = bucket;
    if (bucket < BUCKETS) counts[bucket]++;
  }
  // Exclusive prefix sums: where each bucket's run starts.
  let sum = 0;
  for (let k = 0; k < BUCKETS; k++) {
    const n = counts[k];
    counts[k] = sum;
    sum += n;
  }
  if (map) {
    for (let i = 0; i < count; i++) {
      const bucket = keys[i];
      if (bucket < BUCKETS) out[counts[bucket]++] = map[i];
    }
    if (sum < count) out.fill(map[0], sum);
  } else {
    for (let i = 0; i < count; i++) {
      const bucket = keys[i];
      if (bucket < BUCKETS) out[counts[bucket]++] = i;
    }
  }
  return out;
}

// A Uint32Array of `total` (at least) holding `old`'s values, the rest the identity.
function grownIndex(old, total) {
  const out = new Uint32Array(total);
  for (let i = 0; i < total; i++) out[i] = i;
  if (old) out.set(old.subarray(0, Math.min(old.length, total)));
  return out;
}

self.onmessage = (event) => {
  const msg = event.data;
  if (msg.type === "append") {
    // Positions of records [start, start + n) of a segment, as they stream in.
    let pos = positions.get(msg.segment);
    if (!pos || pos.length < msg.total * 3) {
      const grown = new Float32Array(msg.total * 3);
      if (pos) grown.set(pos.subarray(0, Math.min(pos.length, grown.length)));
      pos = grown;
      positions.set(msg.segment, pos);
    }
    pos.set(msg.positions, msg.start * 3);
    let map = textureIndex.get(msg.segment);
    if (msg.order && (!map || map.length < msg.total)) {
      map = grownIndex(map, msg.total);
      textureIndex.set(msg.segment, map);
    }
    if (msg.order) map.set(msg.order, msg.start);
    else if (map) for (let i = msg.start; i < msg.start + msg.positions.length / 3; i++) map[i] = i;
  } else if (msg.type === "forget") {
    positions.delete(msg.segment);
    textureIndex.delete(msg.segment);
  } else if (msg.type === "sort") {
    const pos = positions.get(msg.segment) || new Float32Array(0);
    const count = Math.min(msg.count, pos.length / 3);
    const t0 = performance.now();
    const index = depthOrder(pos, count, msg.viewProj, textureIndex.get(msg.segment));
    const ms = performance.now() - t0;
    self.postMessage({type: "sorted", segment: msg.segment, id: msg.id, key: msg.key, count, ms, index},
                     [index.buffer]);
  }
};
