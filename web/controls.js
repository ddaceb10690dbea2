// Measurement fields: a labelled slider plus a number box per value, with the valid range from
// `GET /api/bodies/ranges`. Optional measurements start on "auto" (estimated by the server). The pose has
// its own controls (pose.js).
import { PoseControls } from './pose.js';

const LABELS = {
  height: 'Height', chest: 'Chest', waist: 'Waist', hips: 'Hips', shoulder_width: 'Shoulder width',
  arm_length: 'Arm length', inseam: 'Inseam', neck: 'Neck', thigh: 'Thigh', upper_arm: 'Upper arm',
};
const REQUIRED = ['height', 'chest', 'waist', 'hips'];

/**
 * Accept the ranges answer in the shapes the API may use and return
 * {measurements: [{name, min, max, default, required, unit}], pose: [...]}.
 */
export function normaliseRanges(raw) {
  const section = (value, defaults, unit, requiredNames) => {
    if (!value) return [];
    const entries = Array.isArray(value) ? value.map((v) => [v.name, v]) : Object.entries(value);
    return entries.map(([name, v]) => {
      let min, max, def, required;
      if (Array.isArray(v)) {
        [min, max] = v;
      } else {
        min = v.min ?? v.ge ?? v.low;
        max = v.max ?? v.le ?? v.high;
        def = v.default;
        required = v.required;
      }
      if (def === undefined || def === null) def = defaults?.[name];
      if (required === undefined) required = requiredNames ? requiredNames.includes(name) : true;
      const u = v.unit === 'degrees' ? '°' : (v.unit || unit);
      return { name, min: Number(min), max: Number(max), default: def ?? null, required, unit: u,
        description: v.description, estimate: estimates[name] ?? null };
    });
  };
  const m = raw.measurements ?? raw.measurement_ranges ?? {};
  const p = raw.pose ?? raw.pose_ranges ?? {};
  const defaults = raw.defaults ?? {};
  const estimates = raw.estimated_defaults ?? {};
  return {
    measurements: section(m, defaults.measurements ?? raw.measurement_defaults, 'cm', REQUIRED),
    pose: section(p, defaults.pose ?? raw.pose_defaults, '°', null),
  };
}

class Field {
  constructor(spec, container, onChange) {
    this.spec = spec;
    this.auto = !spec.required && (spec.default === null || spec.default === undefined);
    const step = spec.unit === 'cm' ? 0.5 : 1;
    const wrap = document.createElement('div');
    wrap.className = 'field';
    const id = `field-${spec.name}`;
    const label = document.createElement('label');
    label.htmlFor = id;
    label.textContent = LABELS[spec.name] || spec.name.replace(/_/g, ' ');
    const hint = document.createElement('span');
    hint.className = 'range-hint';
    hint.textContent = ` ${fmt(spec.min)}–${fmt(spec.max)} ${spec.unit}`;
    label.append(hint);
    this.autoTag = document.createElement('span');
    this.autoTag.className = 'auto-tag';
    this.autoTag.textContent = 'auto';
    label.append(this.autoTag);
    const slider = document.createElement('input');
    slider.type = 'range';
    slider.min = spec.min; slider.max = spec.max; slider.step = step;
    slider.setAttribute('aria-label', `${label.firstChild.textContent} slider`);
    slider.dataset.name = spec.name;
    const numberBox = document.createElement('div');
    numberBox.className = 'number';
    const number = document.createElement('input');
    number.type = 'number';
    number.id = id;
    number.name = spec.name;
    number.min = spec.min; number.max = spec.max; number.step = step;
    number.inputMode = 'decimal';
    const unit = document.createElement('span');
    unit.className = 'unit';
    unit.textContent = spec.unit;
    numberBox.append(number, unit);
    if (!spec.required && spec.unit === 'cm') {
      // back to "estimated from the required measurements"
      this.reset = document.createElement('button');
      this.reset.type = 'button';
      this.reset.className = 'reset';
      this.reset.textContent = 'auto';
      this.reset.title = 'Estimate it from height, chest, waist and hips';
      this.reset.addEventListener('click', () => {
        number.value = '';
        number.dispatchEvent(new Event('input'));
      });
      label.append(this.reset);
    }
    // what is wrong with the entry, in words under the field (a tooltip alone is not seen on a phone)
    const error = document.createElement('p');
    error.className = 'field-error';
    error.id = `${id}-error`;
    error.setAttribute('role', 'alert');
    error.hidden = true;
    number.setAttribute('aria-describedby', error.id);
    wrap.append(label, numberBox, slider, error);
    container.append(wrap);
    this.wrap = wrap; this.slider = slider; this.number = number; this.error = error;

    const start = spec.default ?? spec.estimate ?? (spec.min + spec.max) / 2;
    slider.value = start;
    number.value = this.auto ? '' : fmt(start);
    number.placeholder = spec.estimate != null ? fmt(spec.estimate) : 'auto';
    if (spec.description) label.title = spec.description;
    this.refreshAuto();
    slider.addEventListener('input', () => {
      this.auto = false;
      number.value = slider.value;
      this.refreshAuto();
      this.validate();
      onChange();
    });
    number.addEventListener('input', () => {
      if (number.value === '' && !spec.required) {
        this.auto = true;
      } else {
        this.auto = false;
        if (this.validate()) slider.value = number.value;
      }
      this.refreshAuto();
      this.validate();
      onChange();
    });
  }

  refreshAuto() {
    this.wrap.classList.toggle('auto', this.auto);
    this.autoTag.hidden = !this.auto;
    if (this.reset) this.reset.hidden = this.auto;
  }

  validate() {
    const v = Number(this.number.value);
    const ok = this.auto || (this.number.value !== '' && Number.isFinite(v) && v >= this.spec.min && v <= this.spec.max);
    if (ok) this.number.removeAttribute('aria-invalid'); else this.number.setAttribute('aria-invalid', 'true');
    const range = `between ${fmt(this.spec.min)} and ${fmt(this.spec.max)} ${this.spec.unit}`;
    this.number.title = ok ? '' : range;
    // an entry the browser cannot read as a number ("17a") reaches here as ''
    this.error.textContent = ok ? '' : (this.number.value === '' ? `Enter a number ${range}.` : `Must be ${range}.`);
    this.error.hidden = ok;
    return ok;
  }

  value() { return this.auto ? null : Number(this.number.value); }

  showEstimate(v) {
    if (this.auto && Number.isFinite(v)) {
      this.number.placeholder = fmt(v);
      this.slider.value = v;
    }
  }
}

function fmt(v) { const x = Number(v); return Number.isInteger(x) ? String(x) : x.toFixed(1); }

export class MeasurementForm {
  /** `raw`: the ranges answer itself (the pose controls read its side fields and named poses);
   * `onPose`: called instead of `onChange` when only the pose changed (null: `onChange`). */
  constructor(ranges, containers, onChange, raw = {}, onPose = null) {
    this.fields = [];
    for (const spec of ranges.measurements) {
      const box = spec.required ? containers.required : containers.optional;
      this.fields.push(new Field(spec, box, onChange));
    }
    this.pose = new PoseControls(raw, containers.pose, () => (onPose ?? onChange)());
  }

  valid() { return this.fields.every((f) => f.validate()); }

  measurements() {
    const out = {};
    for (const f of this.fields) { const v = f.value(); if (v !== null) out[f.spec.name] = v; }
    return out;
  }

  poseValues() { return this.pose.value(); }

  bodyRequest() { return { measurements: this.measurements(), pose: this.poseValues() }; }

  tryOnRequest(garmentId) { return { garment_id: garmentId, ...this.bodyRequest() }; }

  /** Show the built body's measurements as the estimates of the optional fields left on auto. */
  showAchieved(achieved) {
    for (const f of this.fields) if (!f.spec.required) f.showEstimate(achieved[f.spec.name]);
  }

  /** Set a field by name (used by tests and deep links). */
  set(name, value) {
    if (this.pose.has(name)) { this.pose.set(name, value); return; }
    const f = this.fields.find((x) => x.spec.name === name);
    if (!f) throw new Error(`no field ${name}`);
    f.number.value = value;
    f.number.dispatchEvent(new Event('input'));
  }
}
