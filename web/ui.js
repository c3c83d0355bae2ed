// The side panel: scene and mode pickers, split and time sliders, view buttons, the parameters panel
// generated from scene.json `parameters`, and the status, statistics, notices and errors areas.
// It only builds and reads controls; viewer.js decides what they do (the `on*` callbacks).

const COMPONENTS = { float: 1, int: 1, vec2: 2, vec3: 3, vec4: 4 };
const AXES = 'xyzw';
const LOG_STEPS = 1000;

export const srgb = {
  fromLinear: (x) => (x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055),
  toLinear: (x) => (x <= 0.04045 ? x / 12.92 : Math.pow((x + 0.055) / 1.055, 2.4)),
};

/** Linear RGB [r, g, b] -> '#rrggbb' (sRGB, clamped). */
export function linearToHex(rgb) {
  const byte = (v) => Math.round(srgb.fromLinear(Math.min(1, Math.max(0, v))) * 255);
  return '#' + rgb.map((v) => byte(v).toString(16).padStart(2, '0')).join('');
}

/** '#rrggbb' -> linear RGB. */
export function hexToLinear(hex) {
  return [1, 3, 5].map((i) => srgb.toLinear(parseInt(hex.slice(i, i + 2), 16) / 255));
}

function el(tag, props = {}, children = []) {
  const node = document.createElement(tag);
  Object.assign(node, props);
  for (const child of children) node.append(child);
  return node;
}

function formatNumber(v) {
  if (!Number.isFinite(v)) return String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2);
  return String(Number(v.toPrecision(4)));
}

/** A slider for one number of a parameter: linear, log or integer. */
function numberControl(param, label, value, onInput) {
  const { min, max } = param;
  const isInt = param.type === 'int';
  const input = el('input', { type: 'range' });
  let toValue, toPosition;
  if (param.log) {
    input.min = 0;
    input.max = LOG_STEPS;
    input.step = 1;
    toValue = (p) => min * Math.pow(max / min, p / LOG_STEPS);
    toPosition = (v) => (LOG_STEPS * Math.log(Math.max(v, min) / min)) / Math.log(max / min);
  } else {
    input.min = min;
    input.max = max;
    input.step = isInt ? 1 : (max - min) / 1000;
    toValue = (p) => p;
    toPosition = (v) => v;
  }
  const output = el('output', { textContent: formatNumber(value) });
  input.value = toPosition(value);
  input.addEventListener('input', () => {
    let v = toValue(Number(input.value));
    if (isInt) v = Math.round(v);
    output.textContent = formatNumber(v);
    onInput(v);
  });
  const row = el('label', { className: 'param-row', title: param.description || '' }, [
    el('span', { className: 'param-label', textContent: label }), input, output,
  ]);
  row.set = (v) => {
    input.value = toPosition(v);
    output.textContent = formatNumber(v);
  };
  return row;
}

function colourControl(param, label, rgb, onInput) {
  const input = el('input', { type: 'color', value: linearToHex(rgb) });
  const output = el('output', { textContent: linearToHex(rgb) });
  input.addEventListener('input', () => {
    output.textContent = input.value;
    onInput(hexToLinear(input.value));
  });
  const row = el('label', { className: 'param-row', title: param.description || '' }, [
    el('span', { className: 'param-label', textContent: label }), input, output,
  ]);
  row.set = (v) => {
    input.value = linearToHex(v);
    output.textContent = input.value;
  };
  return row;
}

export class Panel {
  constructor(root = document) {
    const $ = (id) => root.getElementById(id);
    this.scene = $('scene');
    this.description = $('scene-description');
    this.mode = $('mode');
    this.modeB = $('mode-b');
    this.splitRow = $('split-row');
    this.split = $('split');
    this.timeRow = $('time-row');
    this.time = $('time');
    this.timeValue = $('time-value');
    this.play = $('play');
    this.continuous = $('continuous');
    this.horizon = $('horizon');
    this.resetView = $('reset-view');
    this.paramSection = $('parameters');
    this.paramList = $('param-list');
    this.paramReset = $('param-reset');
    this.status = $('status');
    this.stats = $('stats');
    this.notices = $('notices');
    this.errors = $('errors');
    this.paramRows = [];
  }

  /** Options of a <select>: items [{value, label}]. */
  fill(select, items, selected) {
    select.replaceChildren(...items.map((it) => el('option', { value: it.value, textContent: it.label })));
    if (selected !== undefined) select.value = selected;
  }

  setStatus(text) {
    this.status.textContent = text;
    this.status.hidden = !text;
  }

  setStats(lines) {
    this.stats.replaceChildren(...lines.map(([k, v]) => el('div', {}, [el('span', { textContent: k + ' ' }), el('b', { textContent: v })])));
  }

  setNotices(list) {
    this.notices.replaceChildren(...list.map((text) => el('li', { textContent: text })));
    this.notices.hidden = !list.length;
  }

  showError(text) {
    this.errors.textContent = text;
    this.errors.hidden = !text;
  }

  showSplit(visible) {
    this.splitRow.hidden = !visible;
  }

  showTime(visible) {
    this.timeRow.hidden = !visible;
  }

  setTime(t) {
    this.time.value = t;
    this.timeValue.textContent = t.toFixed(3);
  }

  /**
   * Controls for every object's parameters. objects: [{name, parameters, value(uniform) -> flat list}].
   * onChange(objectIndex, uniform, flatValues) on every input.
   */
  buildParameters(objects, onChange) {
    this.paramRows = [];
    const groups = [];
    objects.forEach((obj, index) => {
      if (!obj.parameters?.length) return;
      const rows = [];
      for (const p of obj.parameters) {
        const n = COMPONENTS[p.type] || 1;
        const current = [...obj.value(p.uniform)];
        const count = Math.max(1, Math.floor(current.length / n));
        const update = () => onChange(index, p.uniform, [...current]);
        const paramRows = [];
        for (let e = 0; e < count; e++) {
          const suffix = count > 1 ? `[${e}]` : '';
          if (p.colour && n === 3) {
            const row = colourControl(p, p.label + suffix, current.slice(3 * e, 3 * e + 3), (rgb) => {
              current.splice(3 * e, 3, ...rgb);
              update();
            });
            paramRows.push([row, (v) => row.set(v.slice(3 * e, 3 * e + 3))]);
            rows.push(row);
            continue;
          }
          for (let j = 0; j < n; j++) {
            const k = e * n + j;
            const label = p.label + suffix + (n > 1 ? `.${AXES[j]}` : '');
            const row = numberControl(p, label, current[k], (v) => {
              current[k] = v;
              update();
            });
            paramRows.push([row, (v) => row.set(v[k])]);
            rows.push(row);
          }
        }
        this.paramRows.push({ object: index, uniform: p.uniform, current, setters: paramRows.map((r) => r[1]) });
      }
      const heading = objects.length > 1 ? [el('h3', { textContent: obj.name })] : [];
      groups.push(el('div', { className: 'param-group' }, [...heading, ...rows]));
    });
    this.paramList.replaceChildren(...groups);
    this.paramSection.hidden = !groups.length;
  }

  /** Put every parameter control back to values(objectIndex, uniform). */
  resetParameters(values) {
    for (const r of this.paramRows) {
      const v = values(r.object, r.uniform);
      r.current.splice(0, r.current.length, ...v);
      for (const set of r.setters) set(v);
    }
  }
}
