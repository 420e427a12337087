// Evaluated in the page by the browser tests: every layout problem of the visible
// Plotly charts (a figure wider than its cell among them), as text; [] when there is none. Boxes are page pixels. Tick labels and
// titles of every axis count, the stacked subplots' and the deg/s twins' (y2…y6, x2) too.
() => {
  const TICKS = ['x', 'y', 'x2', 'y2', 'y3', 'y4', 'y5', 'y6'].map((a) => `.${a}tick text`).join(', ');
  const TITLES = ['x', 'y', 'x2', 'y2', 'y3', 'y4', 'y5', 'y6'].map((a) => `.g-${a}title text`).join(', ');
  const box = (el) => el.getBoundingClientRect();
  const overlap = (a, b) => {
    const w = Math.min(a.right, b.right) - Math.max(a.left, b.left);
    const h = Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top);
    return w > 1 && h > 1;
  };
  // How far apart two boxes are: 0 or less where they touch or intersect.
  const separation = (a, b) => Math.max(a.left - b.right, b.left - a.right, a.top - b.bottom, b.top - a.bottom);
  const X_TITLES = ['x', 'x2'].map((a) => `.g-${a}title text`).join(', ');
  const problems = [];
  for (const plot of document.querySelectorAll('.js-plotly-plot')) {
    if (!plot.offsetParent) continue;  // hidden (a closed <details>)
    const name = plot.id || '(plot)';
    const svg = plot.querySelector('svg.main-svg');
    if (!svg) continue;
    const figure = box(svg);
    // A figure wider than its cell: Plotly takes a plot's width from its cell once, and
    // the compare page drew its first sweep plot before the second cell was in the grid,
    // 1,212 px wide in a 599 px cell, its highest multiples and legend under the next plot.
    const cell = box(plot);
    if (figure.width > cell.width + 1) problems.push(`${name}: figure ${Math.round(figure.width)} px wide in its ${Math.round(cell.width)} px cell`);
    const legend = plot.querySelector('g.legend');
    const others = [
      ...[...plot.querySelectorAll('.nsewdrag')].map((el) => ['plot area', el]),
      ...[...plot.querySelectorAll(TICKS)].map((el) => ['tick label ' + el.textContent, el]),
      ...[...plot.querySelectorAll(TITLES)].map((el) => ['axis title ' + el.textContent, el]),
      ...[...plot.querySelectorAll('.g-gtitle text')].map((el) => ['title', el]),
      ...[...plot.querySelectorAll('.colorbar')].map((el) => ['colour bar', el]),
    ];
    if (legend && legend.getBBox().width > 0) {
      const lb = box(legend.querySelector('.bg') || legend);
      for (const [what, el] of others) {
        if (el.getBBox && el.getBBox().width === 0) continue;
        if (overlap(lb, box(el))) problems.push(`${name}: legend overlaps ${what}`);
      }
      if (lb.right > figure.right + 1 || lb.left < figure.left - 1) problems.push(`${name}: legend outside the figure`);
      // A legend moved under the plot sat flush against the x-axis title at 375 px (0 px
      // apart, the title's descenders on the legend's first row): apart by 1 px at least.
      for (const el of plot.querySelectorAll(X_TITLES)) {
        if (!el.textContent) continue;
        const apart = separation(lb, box(el));
        if (apart < 1) problems.push(`${name}: legend overlaps x-axis title "${el.textContent}" (${apart.toFixed(1)} px apart)`);
      }
    }
    // Axis titles must not run into each other (stacked subplots) or into tick labels.
    const titles = [...plot.querySelectorAll('[class^="g-"][class$="title"] text')].filter((el) => el.textContent && !el.closest('.g-gtitle'));
    const ticks = [...plot.querySelectorAll(TICKS)].filter((el) => el.textContent);
    titles.forEach((a, i) => {
      for (const b of titles.slice(i + 1)) if (overlap(box(a), box(b))) problems.push(`${name}: axis titles "${a.textContent}" and "${b.textContent}" overlap`);
      for (const t of ticks) if (overlap(box(a), box(t))) problems.push(`${name}: axis title "${a.textContent}" overlaps tick label ${t.textContent}`);
    });
    for (const el of plot.querySelectorAll(`${TITLES}, ${TICKS}, .g-gtitle text`)) {
      if (!el.textContent) continue;
      const b = box(el);
      if (b.left < figure.left - 1 || b.right > figure.right + 1 || b.top < figure.top - 1 || b.bottom > figure.bottom + 1) {
        problems.push(`${name}: "${el.textContent}" is cut at the figure's edge`);
      }
    }
  }
  const wider = document.documentElement.scrollWidth - window.innerWidth;
  if (wider > 0) problems.push(`the page is ${wider} px wider than the window`);
  return problems;
}
