"""The frame of every dashboard page: one self-contained HTML file (inline CSS, inline SVG, no network).

The inline check script (:data:`CHECK_JS`) runs in the browser after layout and marks each chart
(``<svg class="chart">``) with

* ``data-rendered="ok"|"empty"``: every data series has a non-empty laid-out box inside the chart, there are
  as many markers as the chart declares (``data-points``) and the published line (if any) is drawn;
* ``data-labels="ok"|"overlap"``: no two x-axis tick labels, and no two y-axis tick labels, have
  overlapping bounding boxes (``getBoundingClientRect``: what a reader sees, with the browser's fonts);
* ``data-box="left,top,width,height"``: where the chart is in the viewport (CSS px; the screenshot test
  looks there for the series colour);

and each sparkline (``<svg class="spark">``) with ``data-rendered``.  The totals go into
``#render-status`` (``data-charts``, ``data-ok``, ``data-labels-ok``, ``data-sparks``, ``data-sparks-ok``),
read by the headless-Chromium tests.  :data:`FILTER_JS` is the metric finder's filter box: without
JavaScript the box stays hidden and the page is the plain list.
"""
from __future__ import annotations

from typing import Sequence

from bench.report.chart import COLORS, esc

__all__ = ["CSS", "CHECK_JS", "FILTER_JS", "html_page", "legend", "nav_bar"]

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:1.2em 2em;color:#222;max-width:1500px}
h1{font-size:1.5em} h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ddd} h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.88em;margin:.6em 0} td,th{border:1px solid #ccc;padding:2px 7px;text-align:left;vertical-align:top}
th{background:#f2f2f2} td.num{text-align:right;font-variant-numeric:tabular-nums} code{font-size:.95em}
.charts{display:grid;grid-template-columns:repeat(auto-fill,minmax(450px,1fr));gap:10px 14px}
figure{margin:0;border:1px solid #e3e3e3;padding:4px 6px} figcaption{font-size:.82em;margin-bottom:2px}
figcaption .v,.v{color:#555}
svg.chart{display:block;width:100%;height:auto;font-size:10px}
svg .frame{fill:#fff;stroke:#999;stroke-width:1} svg .grid{stroke:#eee;stroke-width:1}
svg .ytick{text-anchor:end;fill:#444} svg .unit{text-anchor:middle;fill:#444}
svg .xtick{text-anchor:middle;fill:#444;font-size:9px;font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,"DejaVu Sans Mono","Liberation Mono",monospace}
svg .band{fill:#3a9d3a;fill-opacity:.13;stroke:none}
svg .published{stroke:#000;stroke-width:1.4;stroke-dasharray:6 4}
svg .publabel{text-anchor:end;font-size:9px;fill:#000}
svg .line{fill:none;stroke-width:1.6} svg .err{fill:none;stroke-width:1.2} svg .pt{stroke:none}
svg .pt.step{stroke:#d00;stroke-width:2.2;fill:#fff}
svg.spark{display:block} svg.spark polyline{fill:none;stroke-width:1.3} svg.spark .published{stroke-width:.8;stroke-dasharray:2 2}
tr.stable:target,svg.chart:target{outline:3px solid #f5b800}
td.c{white-space:nowrap}
.legend span{margin-right:1.2em;font-size:.85em} .sw{display:inline-block;width:18px;height:3px;vertical-align:middle;margin-right:4px}
.bad{color:#b00;font-weight:bold} .ok{color:#070} nav a{margin-right:1em} nav .here{font-weight:bold;margin-right:1em}
details summary{cursor:pointer} ul.metrics{columns:2 38em;font-size:.88em} ul.metrics li{break-inside:avoid}
#metric-filter{font-size:1em;padding:3px 6px;width:30em;max-width:90%}
"""

CHECK_JS = """
(function(){
  function overlap(nodes){var b=[];nodes.forEach(function(t){var r=t.getBoundingClientRect();if(r.width>0&&r.height>0)b.push(r);});
    for(var i=0;i<b.length;i++)for(var j=i+1;j<b.length;j++){var p=b[i],q=b[j];
      if(p.left<q.right-0.5&&q.left<p.right-0.5&&p.top<q.bottom-0.5&&q.top<p.bottom-0.5)return true;}
    return false;}
  var charts=document.querySelectorAll('svg.chart'), ok=0, lok=0, bad=[], crowded=[];
  charts.forEach(function(svg){
    var r=svg.getBoundingClientRect(), g=svg.querySelectorAll('g.series'), pts=svg.querySelectorAll('g.series circle.pt');
    var good=r.width>0&&r.height>0&&g.length>0&&pts.length>0&&pts.length==+svg.getAttribute('data-points');
    g.forEach(function(s){var b=s.getBoundingClientRect();
      if(!(b.width>0&&b.height>0&&b.left>=r.left-1&&b.right<=r.right+1&&b.top>=r.top-1&&b.bottom<=r.bottom+1)) good=false;});
    if(svg.getAttribute('data-published')!==''){var p=svg.querySelector('line.published');
      if(!p||!(p.getBoundingClientRect().width>0)) good=false;}
    svg.setAttribute('data-rendered', good?'ok':'empty');
    svg.setAttribute('data-box', [r.left,r.top,r.width,r.height].map(Math.round).join(','));
    if(good) ok++; else bad.push(svg.id);
    var lab=overlap(svg.querySelectorAll('text.xtick'))||overlap(svg.querySelectorAll('text.ytick'));
    svg.setAttribute('data-labels', lab?'overlap':'ok');
    if(lab) crowded.push(svg.id); else lok++;
  });
  var sparks=document.querySelectorAll('svg.spark'), sok=0;
  sparks.forEach(function(svg){var r=svg.getBoundingClientRect(), good=false;
    svg.querySelectorAll('polyline,circle').forEach(function(e){var b=e.getBoundingClientRect();
      if((b.width>0||b.height>0)&&b.left>=r.left-1&&b.right<=r.right+1) good=true;});
    svg.setAttribute('data-rendered', good?'ok':'empty'); if(good) sok++;});
  var s=document.getElementById('render-status');
  if(s){s.setAttribute('data-charts',charts.length);s.setAttribute('data-ok',ok);s.setAttribute('data-labels-ok',lok);
    s.setAttribute('data-sparks',sparks.length);s.setAttribute('data-sparks-ok',sok);
    s.className=(bad.length||crowded.length||sok<sparks.length)?'bad':'ok';
    s.textContent=ok+' of '+charts.length+' charts rendered'+(bad.length?'; empty: '+bad.join(', '):'')+
      '; '+(crowded.length?'overlapping axis labels: '+crowded.join(', '):'axis labels readable')+
      (sparks.length?'; '+sok+' of '+sparks.length+' sparklines drawn':'');}
})();
"""

FILTER_JS = """
(function(){
  var box=document.getElementById('metric-filter'), items=document.querySelectorAll('#metric-list li'),
      count=document.getElementById('metric-count');
  if(!box) return;
  box.hidden=false;
  function apply(){var words=box.value.toLowerCase().split(/\\s+/).filter(Boolean), n=0;
    items.forEach(function(li){var t=li.getAttribute('data-id').toLowerCase(), show=true;
      words.forEach(function(w){if(t.indexOf(w)<0) show=false;});
      li.hidden=!show; if(show) n++;});
    document.querySelectorAll('#metric-list h3').forEach(function(h){
      var ul=h.nextElementSibling, any=false;
      if(ul) ul.querySelectorAll('li').forEach(function(li){if(!li.hidden) any=true;});
      h.hidden=!any; if(ul) ul.hidden=!any;});
    if(count) count.textContent=n+' of '+items.length+' metrics';}
  box.addEventListener('input', apply);
  if(location.hash.length>1&&location.hash.indexOf('#q=')===0){box.value=decodeURIComponent(location.hash.slice(3));}
  apply();
})();
"""


def html_page(title: str, body: Sequence[str], nav: str, scripts: Sequence[str] = ()) -> str:
    """A whole page: head with the inline CSS, the nav bar, ``<h1>``, the body, the render status and
    the check script (plus ``scripts``)."""
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<nav>{nav}</nav>", f"<h1>{esc(title)}</h1>", *body,
        '<p id="render-status" data-charts="" data-ok="">charts not checked (JavaScript off)</p>',
        f"<script>{CHECK_JS}</script>", *(f"<script>{s}</script>" for s in scripts), "</body></html>", ""])


def _sw(color: str, extra: str = "") -> str:
    return f'<i class="sw" style="background:{color}{extra}"></i>'


def legend(published: bool = True) -> str:
    """The legend of the metric charts (full / quick runs, published value, band, steps)."""
    items = [f"<span>{_sw(COLORS['full'])}full run</span>", f"<span>{_sw(COLORS['quick'])}quick run (--quick)</span>"]
    if published:
        items += [f"<span>{_sw('#000')}published value (dashed)</span>",
                  f"<span>{_sw('#3a9d3a', ';opacity:.35;height:9px')}regression band of metrics.json</span>",
                  '<span><i class="sw" style="background:#fff;border:2px solid #d00;width:6px;height:6px;'
                  'border-radius:50%"></i>moved beyond tolerance since the previous run</span>']
    return f'<p class="legend">{"".join(items)}</p>'


def nav_bar(links: Sequence[tuple[str, str]], here: str = "") -> str:
    """``links`` = (href, text); the current page's link is bold text."""
    return " ".join(f'<span class="here">{esc(t)}</span>' if h == here else f'<a href="{esc(h)}">{esc(t)}</a>'
                    for h, t in links)
