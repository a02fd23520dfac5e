// Pictures for reports: the full-resolution render of the view (`GET /api/render`) with a
// caption, a north arrow, a scale or distance note, the legend (existing / planned plants and
// the mapped data layers' legends) and the attribution drawn over it on a canvas.

/**
 * The lines of a report picture: `caption` (top), `note` (the scale or eye height) and
 * `credit`. `view` is the shown view; `words` the translated strings it needs.
 */
export function reportText(view, words) {
  const planState = words.plan == null ? '' : ` (${words.plan})`;
  return {
    caption: `${view.plan ? words.planCaption : words.caption}${planState}`,
    note: view.plan ? words.width : words.eye,
    credit: words.credit,
  };
}

function box(g, x, y, w, h) {
  g.fillStyle = 'rgba(255, 255, 255, 0.88)';
  g.fillRect(x, y, w, h);
}

/**
 * Draws the report picture: `image` (an ImageBitmap of the render), `text` (`reportText`),
 * `yaw` (the north arrow points to north: up in a plan view), `legend` (`[{label, color}]`)
 * and `legendImages` (loaded legend `<img>`s). Returns the canvas.
 */
export function composeReport(image, text, yaw, legend, legendImages = []) {
  const canvas = document.createElement('canvas');
  canvas.width = image.width;
  canvas.height = image.height;
  const g = canvas.getContext('2d');
  g.drawImage(image, 0, 0);
  const unit = Math.max(12, Math.round(canvas.width / 70));
  const pad = Math.round(unit * 0.6);
  g.font = `600 ${unit}px system-ui, sans-serif`;
  g.textBaseline = 'top';
  // Caption, top left.
  const captionWidth = g.measureText(text.caption).width;
  box(g, pad, pad, captionWidth + 2 * pad, unit + 2 * pad);
  g.fillStyle = '#1c1c22';
  g.fillText(text.caption, 2 * pad, 2 * pad);
  // North arrow, top right.
  const r = unit * 1.6;
  const cx = canvas.width - pad - r;
  const cy = pad + r;
  box(g, cx - r, cy - r, 2 * r, 2 * r);
  g.save();
  g.translate(cx, cy);
  g.rotate((-yaw * Math.PI) / 180);
  g.fillStyle = '#1c1c22';
  g.beginPath();
  g.moveTo(0, -r * 0.8);
  g.lineTo(r * 0.35, r * 0.4);
  g.lineTo(0, r * 0.15);
  g.lineTo(-r * 0.35, r * 0.4);
  g.closePath();
  g.fill();
  g.font = `700 ${Math.round(unit * 0.7)}px system-ui, sans-serif`;
  g.textAlign = 'center';
  g.fillText('N', 0, r * 0.42);
  g.restore();
  // Legend and the note, bottom left; the credit along the bottom.
  g.font = `${Math.round(unit * 0.85)}px system-ui, sans-serif`;
  const line = Math.round(unit * 1.3);
  const rows = [...legend.map((l) => l.label), text.note];
  const width = Math.max(...rows.map((row) => g.measureText(row).width), ...legendImages.map((img) => Math.min(img.naturalWidth, canvas.width / 3)));
  const imagesHeight = legendImages.reduce((sum, img) => sum + Math.round(img.naturalHeight * Math.min(1, canvas.width / 3 / img.naturalWidth)) + pad, 0);
  const height = rows.length * line + imagesHeight + 2 * pad;
  const top = canvas.height - height - line - pad;
  box(g, pad, top, width + 3 * pad + unit, height);
  let y = top + pad;
  for (const { label, color } of legend) {
    g.fillStyle = color;
    g.fillRect(2 * pad, y + unit * 0.1, unit * 0.8, unit * 0.8);
    g.fillStyle = '#1c1c22';
    g.fillText(label, 2 * pad + unit * 1.2, y);
    y += line;
  }
  for (const img of legendImages) {
    const scale = Math.min(1, canvas.width / 3 / img.naturalWidth);
    g.drawImage(img, 2 * pad, y, img.naturalWidth * scale, img.naturalHeight * scale);
    y += Math.round(img.naturalHeight * scale) + pad;
  }
  g.fillStyle = '#1c1c22';
  g.fillText(text.note, 2 * pad, y);
  const creditSize = Math.round(unit * 0.7);
  g.font = `${creditSize}px system-ui, sans-serif`;
  const creditWidth = g.measureText(text.credit).width;
  box(g, canvas.width - creditWidth - 3 * pad, canvas.height - creditSize - 2 * pad, creditWidth + 2 * pad, creditSize + 2 * pad);
  g.fillStyle = '#1c1c22';
  g.fillText(text.credit, canvas.width - creditWidth - 2 * pad, canvas.height - creditSize - pad);
  return canvas;
}
