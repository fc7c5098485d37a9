// URL parameters of the page (README.md): instance=N (or all: every instance
// of the first scene in one view), size=WxH, freeze=F, ws=URL. Pure, so tests
// run it in node.

export class ParamError extends Error {}

function parseCount(text, name, example) {
  if (!/^\d+$/.test(text)) throw new ParamError(`${name}='${text}' is invalid (expected a whole number >= 0, e.g. ${name}=${example})`);
  return Number(text);
}

// "WxH" as in phasecast-render --size: 1..16384 each.
export function parseSize(text) {
  const m = /^(\d+)[xX](\d+)$/.exec(text);
  const w = m ? Number(m[1]) : 0, h = m ? Number(m[2]) : 0;
  if (!m || w < 1 || h < 1 || w > 16384 || h > 16384) {
    throw new ParamError(`size='${text}' is invalid (expected WIDTHxHEIGHT, e.g. size=640x480)`);
  }
  return [w, h];
}

// search: location.search; host: location.host; secure: https page.
export function parseParams(search, host, secure = false) {
  const q = new URLSearchParams(search);
  const get = (name) => (q.has(name) ? q.get(name) : null);
  const instance = get('instance'), size = get('size'), freeze = get('freeze'), ws = get('ws');
  return {
    instance: instance === null ? null : instance === 'all' ? 'all' : parseCount(instance, 'instance', 0),
    size: size === null ? null : parseSize(size),
    freeze: freeze === null ? null : parseCount(freeze, 'freeze', 120),
    ws: ws ?? `${secure ? 'wss' : 'ws'}://${host}/ws`,
  };
}
