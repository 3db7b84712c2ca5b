// Byte rings in SharedArrayBuffers between the server thread and the VM worker.
//
// The VM runs synchronously inside the worker (a `while True: pass` never
// yields to the worker's event loop), so the serial line cannot be carried by
// postMessage alone: the worker must be able to block on input and to publish
// output while Python code is still running.  Each ring has one writer and one
// reader; indices are free-running int32 counters (the size is a power of two).

export const CTL = {
  IN_W: 0, IN_R: 1, OUT_W: 2, OUT_R: 3,
  BUSY: 4,        // worker is inside the VM (set by the worker)
  INJECTED: 5,    // bumped by the server each time it injects a KeyboardInterrupt
  OUT_NOTIFY: 6,  // 1 while an "output ready" message is in flight
  NAP: 7,         // never written: a word to Atomics.wait on for a plain sleep
  FLUSH_TO: 8,    // Ctrl-C: the reader discards input up to this write index ...
  FLUSH_REQ: 9,   // ... when this is 1 (set by the writer after FLUSH_TO, cleared by the reader)
  SIZE: 10,
};

export const IN_SIZE = 1 << 16;
export const OUT_SIZE = 1 << 18;

export function makeShared() {
  return {
    ctl: new SharedArrayBuffer(CTL.SIZE * 4),
    inBuf: new SharedArrayBuffer(IN_SIZE),
    outBuf: new SharedArrayBuffer(OUT_SIZE),
  };
}

export class Ring {
  constructor(ctl, buf, wIdx, rIdx) {
    this.ctl = ctl;
    this.buf = new Uint8Array(buf);
    this.size = this.buf.length;
    this.w = wIdx;
    this.r = rIdx;
  }

  available() {
    return (Atomics.load(this.ctl, this.w) - Atomics.load(this.ctl, this.r)) | 0;
  }

  free() {
    return this.size - this.available();
  }

  // Writes as much of data as fits; returns the number of bytes written.
  write(data, start = 0) {
    const n = Math.min(data.length - start, this.free());
    let w = Atomics.load(this.ctl, this.w);
    for (let i = 0; i < n; i++) {
      this.buf[(w + i) & (this.size - 1)] = data[start + i];
    }
    Atomics.store(this.ctl, this.w, (w + n) | 0);
    return n;
  }

  // Reads up to max bytes (all available if max is omitted).
  read(max = Infinity) {
    const n = Math.min(this.available(), max);
    const r = Atomics.load(this.ctl, this.r);
    const out = new Uint8Array(n);
    for (let i = 0; i < n; i++) {
      out[i] = this.buf[(r + i) & (this.size - 1)];
    }
    Atomics.store(this.ctl, this.r, (r + n) | 0);
    return out;
  }

  readByte() {
    if (this.available() === 0) return -1;
    const r = Atomics.load(this.ctl, this.r);
    const c = this.buf[r & (this.size - 1)];
    Atomics.store(this.ctl, this.r, (r + 1) | 0);
    return c;
  }
}

// Bytes waiting for room in a ring, at most `cap` of them: beyond, new bytes are dropped and
// counted, as a board's UART drops what its buffer cannot hold, instead of growing the host's
// memory.  Chunks are kept as they came (no copying per flush).
export class ByteQueue {
  constructor(cap) {
    this.cap = cap;
    this.clear();
    this.dropped = 0;
  }

  clear() {
    this.chunks = [];
    this.head = 0; // bytes of chunks[0] already moved
    this.length = 0;
  }

  push(buf) {
    const room = this.cap - this.length;
    if (buf.length > room) {
      this.dropped += buf.length - room;
      buf = buf.subarray(0, room);
    }
    if (buf.length) {
      this.chunks.push(buf);
      this.length += buf.length;
    }
  }

  // Moves as much as fits into the ring; returns the number of bytes moved.
  drainInto(ring) {
    let moved = 0;
    while (this.chunks.length) {
      const c = this.chunks[0];
      const n = ring.write(c, this.head);
      moved += n;
      this.head += n;
      this.length -= n;
      if (this.head < c.length) break;
      this.chunks.shift();
      this.head = 0;
    }
    return moved;
  }
}
