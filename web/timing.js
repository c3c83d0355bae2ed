// Frame time: GPU time per frame from EXT_disjoint_timer_query_webgl2 (TIME_ELAPSED_EXT queries,
// polled in later frames, discarded when GPU_DISJOINT_EXT is raised), else the median interval
// between requestAnimationFrame callbacks. `value` says which one it is.

const WINDOW = 60;

function median(values) {
  if (!values.length) return NaN;
  const s = [...values].sort((a, b) => a - b);
  const m = s.length >> 1;
  return s.length % 2 ? s[m] : (s[m - 1] + s[m]) / 2;
}

export class FrameTimer {
  constructor(gl, timerExt) {
    this.gl = gl;
    this.ext = timerExt;
    this.pending = []; // queries in flight, oldest first
    this.free = [];
    this.active = null;
    this.gpu = [];
    this.intervals = [];
    this.last = null;
    this.stale = 0; // pending queries that belong to before the last reset()
  }

  /** Call at the start of a frame with the rAF timestamp. */
  begin(now) {
    if (this.last !== null) {
      this.intervals.push(now - this.last);
      if (this.intervals.length > WINDOW) this.intervals.shift();
    }
    this.last = now;
    if (!this.ext) return;
    this.poll();
    if (this.pending.length > 8) return; // results are late: do not pile up queries
    this.active = this.free.pop() || this.gl.createQuery();
    this.gl.beginQuery(this.ext.TIME_ELAPSED_EXT, this.active);
  }

  end() {
    if (!this.active) return;
    this.gl.endQuery(this.ext.TIME_ELAPSED_EXT);
    this.pending.push(this.active);
    this.active = null;
  }

  poll() {
    const gl = this.gl;
    const disjoint = gl.getParameter(this.ext.GPU_DISJOINT_EXT);
    while (this.pending.length) {
      const q = this.pending[0];
      if (!disjoint && !gl.getQueryParameter(q, gl.QUERY_RESULT_AVAILABLE)) break;
      this.pending.shift();
      if (this.stale > 0) this.stale--;
      else if (!disjoint) {
        this.gpu.push(gl.getQueryParameter(q, gl.QUERY_RESULT) / 1e6);
        if (this.gpu.length > WINDOW) this.gpu.shift();
      }
      this.free.push(q);
    }
  }

  /** A frame was skipped (nothing drawn): forget the interval across it. */
  pause() {
    this.last = null;
  }

  /** Forget the measurements (a new scene or mode): in-flight queries are dropped as they land. */
  reset() {
    this.gpu = [];
    this.intervals = [];
    this.last = null;
    this.stale = this.pending.length;
  }

  /** Nothing drawn this frame: keep collecting the results of earlier queries. */
  idle() {
    this.last = null;
    if (this.ext && this.pending.length) this.poll();
  }

  /** {ms, source}: 'GPU' when timer queries have answered, else 'rAF interval'. */
  get value() {
    if (this.gpu.length) return { ms: median(this.gpu), source: 'GPU' };
    return { ms: median(this.intervals), source: 'rAF interval' };
  }
}
