// Pose controls: a select of the named poses (GET /api/bodies/ranges `named_poses`) and, per joint, one
// slider for each side (left | right, the body's own), compact: a row per joint. "Both sides alike" moves the
// other side's slider with the one moved. The request's pose is the name while the sliders show it unchanged,
// else the side angles.

const JOINTS = [
  ['arm_angle', 'Arm out'], ['arm_forward', 'Arm forwards'], ['arm_rotation', 'Arm turn'],
  ['elbow_bend', 'Elbow'], ['wrist_bend', 'Wrist'], ['leg_spread', 'Leg out'],
];
const NAMES = {
  a_pose: 'A-pose', arms_down: 'Arms down', hands_on_hips: 'Hands on hips', arms_raised: 'Arms raised',
  stride: 'Stride',
};
const SIDES = ['left', 'right'];

export class PoseControls {
  /**
   * @param {object} raw the ranges answer ({pose: {name: {min, max, default, description}}, named_poses})
   * @param {HTMLElement} container where the controls go
   * @param {() => void} onChange called after every change a person makes
   */
  constructor(raw, container, onChange) {
    this.ranges = raw.pose ?? {};
    this.named = raw.named_poses ?? {};
    this.onChange = onChange;
    this.sliders = {};
    this.outputs = {};

    const top = document.createElement('div');
    top.className = 'pose-top';
    const label = document.createElement('label');
    label.htmlFor = 'pose-name';
    label.textContent = 'Preset';
    this.select = document.createElement('select');
    this.select.id = 'pose-name';
    for (const name of Object.keys(this.named)) {
      const option = new Option(NAMES[name] ?? name.replace(/_/g, ' '), name);
      option.title = this.named[name].description ?? '';
      this.select.append(option);
    }
    this.select.append(new Option('Custom', ''));
    const linkLabel = document.createElement('label');
    linkLabel.className = 'pose-link';
    this.link = document.createElement('input');
    this.link.type = 'checkbox';
    this.link.id = 'pose-link';
    this.link.checked = true;
    linkLabel.append(this.link, document.createTextNode(' both sides alike'));
    top.append(label, this.select, linkLabel);

    const grid = document.createElement('div');
    grid.className = 'pose-grid';
    grid.setAttribute('role', 'group');
    grid.setAttribute('aria-label', 'Pose angles, each side');
    const head = ['', 'Left', 'Right'].map((t) => {
      const h = document.createElement('span');
      h.className = 'pose-head';
      h.textContent = t;
      return h;
    });
    grid.append(...head);
    for (const [joint, text] of JOINTS) {
      const left = this.ranges[`${joint}_left`];
      if (!left) continue;
      const row = document.createElement('span');
      row.className = 'pose-joint';
      row.textContent = text;
      row.title = (this.ranges[joint] ?? left).description ?? '';
      grid.append(row);
      for (const side of SIDES) {
        const name = `${joint}_${side}`;
        const spec = this.ranges[name];
        const cell = document.createElement('span');
        cell.className = 'pose-cell';
        const slider = document.createElement('input');
        slider.type = 'range';
        slider.id = `pose-${name}`;
        slider.min = spec.min; slider.max = spec.max; slider.step = 1;
        slider.value = spec.default ?? 0;
        slider.dataset.name = name;
        slider.setAttribute('aria-label', `${text}, ${side}, degrees`);
        const out = document.createElement('output');
        out.htmlFor = slider.id;
        out.textContent = `${slider.value}°`;
        cell.append(slider, out);
        grid.append(cell);
        this.sliders[name] = slider;
        this.outputs[name] = out;
        slider.addEventListener('input', () => {
          if (this.link.checked) {
            const other = this.sliders[`${joint}_${side === 'left' ? 'right' : 'left'}`];
            other.value = slider.value;
          }
          this.select.value = '';
          this.refresh();
          this.onChange();
        });
      }
    }
    container.append(top, grid);
    this.select.addEventListener('change', () => {
      if (this.select.value) this.show(this.select.value);
      this.onChange();
    });
    this.select.value = 'a_pose' in this.named ? 'a_pose' : '';
  }

  /** Show the named pose's angles on the sliders. */
  show(name) {
    const angles = this.named[name]?.angles ?? {};
    for (const [k, v] of Object.entries(angles)) if (this.sliders[k]) this.sliders[k].value = v;
    this.select.value = name;
    this.link.checked = SIDES.length && Object.keys(this.sliders).every((k) => !k.endsWith('_left')
      || this.sliders[k].value === this.sliders[k.replace(/_left$/, '_right')].value);
    this.refresh();
  }

  refresh() {
    for (const [k, s] of Object.entries(this.sliders)) this.outputs[k].textContent = `${s.value}°`;
  }

  /** The request's pose: the named pose's name, or every side's angle (degrees). */
  value() {
    if (this.select.value) return this.select.value;
    const out = {};
    for (const [k, s] of Object.entries(this.sliders)) out[k] = Number(s.value);
    return out;
  }

  /** Set a side angle (name like `arm_angle_left`, or the shorthand `arm_angle` for both), or a named pose
   * (`set('pose', 'hands_on_hips')`): for tests and deep links. */
  set(name, value) {
    if (name === 'pose') { this.show(value); this.onChange(); return; }
    const names = this.sliders[name] ? [name] : SIDES.map((s) => `${name}_${s}`);
    if (!names.every((n) => this.sliders[n])) throw new Error(`no pose field ${name}`);
    for (const n of names) this.sliders[n].value = value;
    this.select.value = '';
    this.refresh();
    this.onChange();
  }

  /** Whether a name is a pose field here. */
  has(name) { return name === 'pose' || Boolean(this.sliders[name] || this.sliders[`${name}_left`]); }
}
