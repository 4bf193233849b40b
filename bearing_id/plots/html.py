# noqa: A005  (imported only as bearing_id.plots.html; renaming the module would change the public API)
"""
A self-contained HTML report page: inline CSS, images embedded as base64 PNG, no network access at all.

The page forbids every fetch with a Content-Security-Policy (``default-src 'none'``; images only from ``data:``),
so it renders the same offline, from an e-mail attachment or a CI artifact.  A small inline script records, into
the element ``#render-check``, how many images the browser decoded (``naturalWidth > 0``) and any script error or
``console.error`` -- the headless-browser check (test/test_report.py) reads it back from the rendered DOM.
"""
from __future__ import annotations

import argparse
import base64
import html
import os
from pathlib import Path
import re
import shutil
import subprocess
import tempfile

CSS = """
body{font-family:-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:0;color:#1a1a1a;background:#fff}
main{max-width:1320px;margin:0 auto;padding:16px 28px 40px}
h1{font-size:1.6em;margin:.4em 0 .2em} h2{font-size:1.25em;margin:1.6em 0 .4em;border-bottom:2px solid #ddd;
padding-bottom:.2em} h3{font-size:1.05em;margin:1.2em 0 .3em}
p,li{line-height:1.45;max-width:1100px} .muted{color:#666;font-size:.9em}
table{border-collapse:collapse;margin:.5em 0 1em;font-size:.86em} th,td{border:1px solid #ccc;padding:3px 7px;
text-align:right;white-space:nowrap} th{background:#f2f2f2} td.l,th.l{text-align:left}
td.undet{color:#888;font-style:italic} td.warn,span.warn{color:#b00;font-weight:600} td.ok{color:#070}
figure{margin:.6em 0 1.4em} figure img{max-width:100%;height:auto;border:1px solid #e4e4e4}
figcaption{font-size:.88em;color:#333;max-width:1100px;margin-top:.2em}
pre{background:#f7f7f7;border:1px solid #e4e4e4;padding:8px;font-size:.8em;overflow-x:auto}
nav{font-size:.9em;margin:.6em 0} nav a{margin-right:1em} .kv td:first-child{text-align:left;font-weight:600}
.kv td{text-align:left;white-space:normal} #render-check{color:#999;font-size:.75em;margin-top:2em}
.row{display:flex;flex-wrap:wrap;gap:16px;align-items:flex-start} .row figure{flex:1 1 600px;margin:.6em 0}
"""

CHECK_SCRIPT = """
(function(){
  var errs=[];
  window.addEventListener('error',function(e){errs.push('error: '+(e.message||(e.target&&e.target.tagName)||e.type));},
                          true);
  var ce=console.error;
  console.error=function(){errs.push('console.error: '+Array.prototype.join.call(arguments,' '));
                           return ce.apply(console,arguments);};
  window.addEventListener('load',function(){
    var im=document.images,ok=0,bad=[];
    for(var i=0;i<im.length;i++){if(im[i].complete&&im[i].naturalWidth>0){ok++;}else{bad.push(im[i].alt||String(i));}}
    var d=document.getElementById('render-check');
    d.setAttribute('data-images',String(im.length));
    d.setAttribute('data-decoded',String(ok));
    d.setAttribute('data-bad',bad.join(' | '));
    d.setAttribute('data-errors',errs.join(' | '));
    d.setAttribute('data-done','1');
    d.textContent='page check: '+ok+' of '+im.length+' images decoded'+(errs.length?'; errors: '+errs.join('; '):
                  '; no script errors');
  });
})();
"""

CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def _cls(klass) -> str:
    return ' class="' + esc(klass) + '"' if klass else ''


class Page:
    """Build the page section by section; :meth:`render` returns the HTML text, :meth:`write` saves it."""

    def __init__(self, title: str):
        self.title = title
        self.parts: list[str] = []
        self.toc: list[tuple[str, str]] = []
        self.n_images = 0

    def section(self, title: str, anchor: str | None = None) -> None:
        anchor = anchor or 's' + str(len(self.toc) + 1)
        self.toc.append((anchor, title))
        self.parts.append(f'<h2 id="{esc(anchor)}">{esc(title)}</h2>')

    def subsection(self, title: str) -> None:
        self.parts.append(f'<h3>{esc(title)}</h3>')

    def paragraph(self, text: str, cls: str | None = None) -> None:
        self.parts.append(f'<p{_cls(cls)}>{esc(text)}</p>')

    def raw(self, html_text: str) -> None:
        self.parts.append(html_text)

    def bullets(self, items) -> None:
        self.parts.append('<ul>' + ''.join(f'<li>{esc(i)}</li>' for i in items) + '</ul>')

    def pre(self, text: str, summary: str | None = None) -> None:
        block = f'<pre>{esc(text)}</pre>'
        self.parts.append(f'<details><summary>{esc(summary)}</summary>{block}</details>' if summary else block)

    def table(self, header, rows, *, caption: str | None = None, left_cols: int = 1, cls: str | None = None) -> None:
        """rows: lists of cells; a cell is text or (text, css class)."""
        def cell(tag, c, i):
            text, klass = (c if isinstance(c, tuple) else (c, ''))
            klass = ' '.join(x for x in (klass, 'l' if i < left_cols else '') if x)
            return f'<{tag}{_cls(klass)}>{esc(text)}</{tag}>'
        out = [f'<table{_cls(cls)}>']
        if caption:
            out.append(f'<caption class="muted">{esc(caption)}</caption>')
        if header:
            out.append('<tr>' + ''.join(cell('th', h, i) for i, h in enumerate(header)) + '</tr>')
        for r in rows:
            out.append('<tr>' + ''.join(cell('td', c, i) for i, c in enumerate(r)) + '</tr>')
        out.append('</table>')
        self.parts.append(''.join(out))

    def image(self, png: bytes, caption: str, alt: str) -> None:
        """Embed PNG bytes as a base64 data URI with a caption (ValueError for anything but PNG data)."""
        if png[:8] != b'\x89PNG\r\n\x1a\n':
            raise ValueError(f'{alt}: not PNG data')
        b64 = base64.b64encode(png).decode('ascii')
        self.n_images += 1
        self.parts.append(f'<figure><img alt="{esc(alt)}" src="data:image/png;base64,{b64}">'
                          f'<figcaption>{esc(caption)}</figcaption></figure>')

    def row_start(self) -> None:
        """Images until :meth:`row_end` sit side by side (wrapping on narrow screens)."""
        self.parts.append('<div class="row">')

    def row_end(self) -> None:
        self.parts.append('</div>')

    def render(self, header_html: str = '', footer_text: str = '') -> str:
        nav = '<nav>' + ''.join(f'<a href="#{esc(a)}">{esc(t)}</a>' for a, t in self.toc) + '</nav>'
        return ('<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
                f'<meta http-equiv="Content-Security-Policy" content="{CSP}">'
                '<meta name="viewport" content="width=device-width, initial-scale=1">'
                f'<title>{esc(self.title)}</title><style>{CSS}</style><script>{CHECK_SCRIPT}</script></head>\n'
                f'<body><main><h1>{esc(self.title)}</h1>{header_html}{nav}\n'
                + '\n'.join(self.parts)
                + f'\n<p class="muted">{esc(footer_text)}</p><div id="render-check">page check: not run '
                  '(scripts disabled?)</div></main></body></html>\n')

    def write(self, path, **kw) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.render(**kw), encoding='utf-8')
        return path


# ------------------------------------------------------------------------------------------------ browser check
CHROMIUM_FLAGS = ('--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
                  '--disable-background-networking', '--disable-component-update', '--disable-sync',
                  '--enable-logging=stderr', '--v=0')


def find_chromium() -> str | None:
    """Path of a Chromium / Chrome executable (``CHROMIUM`` overrides), or None."""
    env = os.environ.get('CHROMIUM')
    if env:
        return env
    for name in ('chromium', 'chromium-browser', 'google-chrome', 'google-chrome-stable'):
        p = shutil.which(name)
        if p:
            return p
    return None


def browser_check(path, *, chromium: str | None = None, screenshot=None, window=(1400, 2000),
                  timeout: float = 120.0) -> dict:
    """
    Render the page ``path`` in headless Chromium and read back what it saw.

    Returns {'images': n, 'decoded': n with naturalWidth > 0, 'bad': [alt], 'errors': [script errors and
    console.error calls recorded by the page], 'console': [every console line Chromium logged], 'done': the load
    handler ran}.  With ``screenshot`` also writes a PNG of the first ``window`` = (width, height) pixels.
    Raises FileNotFoundError when no Chromium is installed, RuntimeError when it fails.
    """
    exe = chromium or find_chromium()
    if exe is None:
        raise FileNotFoundError('no chromium executable (apt-get install chromium, or set CHROMIUM)')
    url = Path(path).resolve().as_uri()
    with tempfile.TemporaryDirectory(prefix='bearing_id_chromium_') as prof:
        base = [exe, *CHROMIUM_FLAGS, f'--user-data-dir={prof}']
        r = subprocess.run(base + ['--dump-dom', url], capture_output=True, text=True, timeout=timeout)
        if r.returncode != 0:
            raise RuntimeError(f'chromium exited {r.returncode}: {r.stderr[-2000:]}')
        if screenshot is not None:
            shot = Path(screenshot).resolve()
            shot.parent.mkdir(parents=True, exist_ok=True)
            s = subprocess.run(base + ['--hide-scrollbars', f'--screenshot={shot}',
                                       f'--window-size={int(window[0])},{int(window[1])}', url],
                               capture_output=True, text=True, timeout=timeout)
            if s.returncode != 0 or not shot.exists():
                raise RuntimeError(f'chromium screenshot failed ({s.returncode}): {s.stderr[-2000:]}')
    m = re.search(r'<div id="render-check"([^>]*)>', r.stdout)
    attrs = dict(re.findall(r'data-([a-z]+)="([^"]*)"', m.group(1))) if m else {}
    console = [ln for ln in r.stderr.splitlines() if ':CONSOLE' in ln]
    split = (lambda v: [x for x in html.unescape(v).split(' | ') if x]) if attrs else (lambda v: [])
    return {'images': int(attrs.get('images', -1)), 'decoded': int(attrs.get('decoded', -1)),
            'bad': split(attrs.get('bad', '')), 'errors': split(attrs.get('errors', '')), 'console': console,
            'done': attrs.get('done') == '1'}


def _main(argv=None) -> int:
    """``python -m bearing_id.plots.html PAGE [--screenshot PNG]``: the browser check, printed."""
    ap = argparse.ArgumentParser(prog='python -m bearing_id.plots.html', description=browser_check.__doc__)
    ap.add_argument('page')
    ap.add_argument('--screenshot')
    ap.add_argument('--window', default='1400,2000', help='WIDTH,HEIGHT of the screenshot [px]')
    a = ap.parse_args(argv)
    w = tuple(int(v) for v in a.window.split(','))
    res = browser_check(a.page, screenshot=a.screenshot, window=w)
    print(res)
    ok = res['done'] and res['images'] == res['decoded'] and not res['errors'] and not res['console']
    return 0 if ok else 1


__all__ = ['Page', 'esc', 'CSP', 'find_chromium', 'browser_check']

if __name__ == '__main__':  # pragma: no cover
    raise SystemExit(_main())
