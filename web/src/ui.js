// The page's controls (index.html): instance picker, one button per palette
// entry, status line, error line, download progress and the HUD. Only DOM
// here; what the controls do is main.js's.

const $ = (id) => document.getElementById(id);

export class Ui {
  constructor({ onPickInstance, onPickTarget, onImpulse }) {
    this.picker = $('instance');
    this.target = $('target');  // with every instance in view: which one the palette drives
    this.palette = $('palette');
    this.status = $('status');
    this.error = $('error');
    this.progress = $('progress');
    this.hud = $('hud');
    this.canvas = $('view');
    this.picker.addEventListener('change', () =>
      onPickInstance(this.picker.value === 'all' ? 'all' : Number(this.picker.value)));
    this.target.addEventListener('change', () => onPickTarget());
    this.palette.addEventListener('click', (e) => {
      const button = e.target.closest('button[data-palette]');
      if (button && !button.disabled) onImpulse(button.dataset.palette);
    });
  }

  // instances: [{instance, scene}], followed: the id shown, or 'all';
  // allScene: the scene "all instances" shows (null: no such entry).
  setInstances(instances, followed, allScene) {
    const wanted = `${instances.map((i) => `${i.instance}:${i.scene}`).join()}/${allScene}`;
    if (this.picker.dataset.list !== wanted) {
      const scene = allScene;
      const all = scene ? [new Option(`all instances of '${scene}'`, 'all')] : [];
      this.picker.replaceChildren(...instances.map((i) => new Option(`instance ${i.instance} — ${i.scene}`, String(i.instance))),
        ...all);
      this.picker.dataset.list = wanted;
    }
    if (followed !== null) this.picker.value = String(followed);
  }

  // ids: the instances in view when they are several (else none: no picker);
  // the palette then drives `target`, one of them or 'all'.
  setTargets(ids) {
    const shown = ids.length > 1;
    this.target.hidden = !shown;
    this.target.labels.forEach((l) => { l.hidden = !shown; });
    const wanted = ids.join();
    if (this.target.dataset.list === wanted) return;
    const keep = this.target.value;
    this.target.replaceChildren(new Option('all of them', 'all'), ...ids.map((id) => new Option(`instance ${id}`, String(id))));
    this.target.dataset.list = wanted;
    if ([...this.target.options].some((o) => o.value === keep)) this.target.value = keep;
  }

  // The palette's target: 'all' or an instance id.
  targetValue() {
    return this.target.value === 'all' || this.target.value === '' ? 'all' : Number(this.target.value);
  }

  // entries: [{name, index, enabled}] of the followed instance's scene.
  setPalette(entries) {
    const names = entries.map((e) => e.name).join();
    if (this.palette.dataset.names !== names) {
      this.palette.replaceChildren(...entries.map((e) => {
        const button = document.createElement('button');
        button.type = 'button';
        button.textContent = e.name;
        button.dataset.palette = e.name;
        button.title = `palette entry ${e.index}: apply ${e.name}`;
        return button;
      }));
      this.palette.dataset.names = names;
    }
    entries.forEach((e, i) => (this.palette.children[i].disabled = !e.enabled));
  }

  setStatus(text) {
    this.status.textContent = text;
  }

  // An error line stays until replaced or cleared (text null).
  setError(text) {
    this.error.textContent = text ?? '';
    this.error.hidden = !text;
  }

  setProgress(done, total) {
    this.progress.hidden = done >= total;
    this.progress.max = total;
    this.progress.value = done;
  }

  setHud(lines) {
    this.hud.textContent = lines.join('\n');
  }

  // size: [w, h] fixed (CSS pixels = drawing-buffer pixels), or null: fill
  // the view area at the device pixel ratio. Returns true when it changed.
  sizeCanvas(size) {
    const c = this.canvas;
    let w, h;
    if (size) {
      [w, h] = size;
      c.style.width = `${w}px`;
      c.style.height = `${h}px`;
    } else {
      const ratio = window.devicePixelRatio || 1;
      w = Math.max(1, Math.round(c.clientWidth * ratio));
      h = Math.max(1, Math.round(c.clientHeight * ratio));
    }
    if (c.width === w && c.height === h) return false;
    c.width = w;
    c.height = h;
    return true;
  }
}
