// Every word the page shows, in English and German, and the language switch. Elements carry
// `data-i18n="key"` (text), `data-i18n-label="key"` (aria-label), `data-i18n-title="key"`
// (title) or `data-i18n-placeholder="key"`; scripts call `t(key, values)`. Values fill `{name}`
// placeholders. A key missing in a language falls back to English.

const STORE_KEY = 'landsketch.language';

/** The strings, by language and key. */
export const STRINGS = {
  en: {
    'app.name': 'landsketch',
    'lang.label': 'Language',
    'mode.login': 'Planner login',
    'mode.logout': 'Log out',
    'mode.planner': 'Planner mode',
    'login.title': 'Planner login',
    'login.token': 'Admin token',
    'login.help': 'Planners change what every visitor sees: upload data, edit the drawing style and delete layers. Enter the admin token the server was started with.',
    'login.open': 'This server has no admin token: planner changes are accepted from this computer only.',
    'login.submit': 'Log in',
    'login.cancel': 'Cancel',
    'login.wrong': 'That token was not accepted: {reason}',
    'login.ok': 'Logged in as planner.',
    'login.out': 'Logged out: the planner controls are hidden.',
    'login.expired': 'The planner login is no longer valid; log in again.',
    'conn.connecting': 'connecting…',
    'conn.open': 'connected',
    'conn.retry': 'disconnected — retrying in {s} s',
    'conn.reconnect': 'Reconnect now',
    'view.label': 'Landscape view. Drag to look around, W A S D or arrow keys to walk, Q and E to go lower or higher; on touch screens one finger looks, two fingers walk, pinch zooms.',
    'view.waiting': 'Waiting for the first picture…',
    'view.rendering': 'Drawing a sharp picture…',
    'view.compass': 'Compass: the view looks {dir} ({deg}°)',
    'dir.n': 'north', 'dir.ne': 'north-east', 'dir.e': 'east', 'dir.se': 'south-east',
    'dir.s': 'south', 'dir.sw': 'south-west', 'dir.w': 'west', 'dir.nw': 'north-west',
    'hint.title': 'How to move',
    'hint.touch': 'One finger: look around · two fingers: walk · pinch: zoom · tap a button below to fly up or see the plan.',
    'hint.mouse': 'Drag: look around · W A S D or arrow keys: walk · Q / E: lower / higher · wheel: walking speed.',
    'hint.close': 'Got it',
    'tool.label': 'View',
    'tool.walk': 'Walk',
    'tool.fly': 'Fly up for an overview',
    'tool.flyTitle': 'Lift the eye up and look around from above (F)',
    'tool.bird': "Bird's-eye view",
    'tool.birdTitle': 'The map seen from straight above, north up (P)',
    'tool.reset': 'Back to the start',
    'tool.goPlan': 'Go to the plan',
    'tool.withPlan': 'With the plan',
    'tool.highlight': 'Highlight the plan',
    'tool.speed': 'Walking speed',
    'tool.resolution': 'Picture sharpness',
    'res.low': 'rough', 'res.half': 'fast', 'res.full': 'sharp',
    'tool.screenshot': 'Save picture',
    'tool.share': 'Share link',
    'tool.rendering': 'Drawing…',
    'link.label': 'Link to this view',
    'link.copied': 'Link copied.',
    'link.select': 'Copy the selected link (the clipboard is not available).',
    'shot.saved': 'Picture {w} × {h} pixels saved.',
    'shot.failed': 'The picture could not be saved: {reason}',
    'shot.caption': '{title} — view to the {dir}',
    'shot.plan': '{title} — seen from above',
    'shot.withPlan': 'with the plan', 'shot.withoutPlan': 'without the plan',
    'shot.width': 'Picture {m} m across',
    'shot.distance': 'Eye {h} m above the ground',
    'shot.credit': 'Drawn with landsketch',
    'welcome.label': 'About this place',
    'welcome.controls': 'How to look around',
    'welcome.c1': 'Walk: drag the picture to look around; W A S D or the arrow keys walk (on a phone: two fingers).',
    'welcome.c2': 'Fly up for an overview, or switch to the bird\'s-eye view to see the whole area as a map.',
    'welcome.c3': '"Go to the plan" takes you to where the change is; "With the plan" shows the landscape with and without it.',
    'legend.title': 'What you see',
    'legend.existing': 'Existing trees and shrubs',
    'legend.planned': 'Planned planting',
    'legend.plannedOff': 'Planned planting (hidden now)',
    'looks.title': 'Look',
    'looks.sketch': 'Pen sketch',
    'looks.colour': 'Sketch with colour',
    'looks.photo': 'Like a photo',
    'looks.book': 'Picture book',
    'data.title': 'Maps on the landscape',
    'data.none': 'No data maps are published for this place yet.',
    'map.title': 'Map',
    'map.label': 'Small map: you are here (dot), what you see (cone), planned areas (outline) and viewpoints (squares). Tap to go there.',
    'map.here': 'you are here',
    'scale.label': '{m} m',
    'msg.notReady': 'The server is not ready: {reason}. Reload the page in a moment.',
    'msg.refused': "This link's view was refused ({reason}); showing the default view.",
    'msg.layers': 'Cannot list the data layers: {reason}',
    'msg.style': 'Cannot show the style: {reason}',
    'msg.deleted': 'Deleted “{name}”.',
    'msg.deleteFailed': 'Cannot delete “{name}”: {reason}',
    'msg.confirmDelete': 'Delete the layer “{name}” and all its time steps? This cannot be undone.',
    'msg.newLayer': 'A new data layer is available: “{name}”.',
    'msg.noPlan': 'This scene names no planned layer.',
    'tab.style': 'Style', 'tab.data': 'Data', 'tab.upload': 'Upload', 'tab.art': 'Art maps', 'tab.about': 'About',
    'panel.toggle': 'Panels',
    'panel.label': 'Controls',
    'style.target': 'Style of',
    'style.whole': 'the whole view',
    'style.preset': 'Look (preset)',
    'style.none': 'none (defaults)',
    'style.reset': 'Reset style',
    'style.main': 'Main',
    'style.advanced': 'Advanced',
    'stats.title': 'pictures per second · control to picture · round trip · drawing time',
    'layer.coverage': 'Covers {pct} % of the scene.',
    'layer.outside': 'This layer lies outside the scene.',
    'layer.goto': 'Go to layer',
    'layer.delete': 'Delete…',
    'layer.units': 'Units: {u}',
    'layer.noUnits': 'none given',
    'layer.legend': 'Legend of {name}',
    'layer.steps': '{n} time steps',
    'layer.classes': '{n} classes',
    'style.f.visible': 'Show this layer',
    'style.f.photorealism': 'Realism (drawing → photo)',
    'style.f.hlp_abstraction': 'Simplify tree crowns',
    'style.f.leaf_size': 'Leaf size',
    'style.f.leaf_shape': 'Leaf shape',
    'style.f.contour_threshold': 'Outline detail',
    'style.f.contour_strength': 'Outline darkness',
    'style.f.silhouette_map': 'Outline stroke style',
    'style.f.hatch_map': 'Hatching pattern',
    'style.f.hatch_brightness': 'Hatching lightness',
    'style.f.tone_contrast': 'Light and shadow contrast',
    'style.f.color': 'Amount of colour',
    'style.f.color_saturation': 'Colour strength',
    'style.f.color_abstraction': 'Simplify colours',
    'tool.tour': 'Tour',
    'tour.start': 'Where we start',
    'tour.startCaption': 'The place as it is today, from where the visit starts.',
    'tour.overview': 'Overview',
    'tour.overviewCaption': 'The whole area from above the start.',
    'tour.plan': 'The plan',
    'tour.planCaption': 'The planned planting, seen from nearby.',
    'tour.step': '{name} ({i} of {n})',
    'meeting.open': 'Start a meeting',
    'meeting.presenting': 'Meeting {code}: you present',
    'meeting.following': 'Meeting {code}: you follow the presenter',
    'meeting.detached': 'Meeting {code}: you explore on your own',
    'meeting.followers': '{n} following · join at {url}',
    'meeting.detach': 'Explore on my own',
    'meeting.rejoin': 'Follow the presenter again',
    'meeting.close': 'End the meeting',
    'meeting.ended': 'The meeting ended: {reason}',
    'meeting.qr': 'QR code to join meeting {code}',
    'mapping.showAs': 'Show on the landscape as',
    'mapping.none': 'not shown',
    'mapping.color': 'colour',
    'mapping.hatch_tone': 'darker or lighter hatching',
    'mapping.hatch_color': 'coloured hatching',
    'mapping.hatch_pattern': 'hatching pattern',
    'mapping.silhouette_style': 'outline style',
    'mapping.silhouette_density': 'outline density',
    'mapping.abstraction': 'simpler or more detailed plants',
    'confirm.cancel': 'Cancel',
    'confirm.delete': 'Delete',
  },
  de: {
    'lang.label': 'Sprache',
    'mode.login': 'Anmeldung Planung',
    'mode.logout': 'Abmelden',
    'mode.planner': 'Planungsmodus',
    'login.title': 'Anmeldung für Planende',
    'login.token': 'Admin-Schlüssel',
    'login.help': 'Planende ändern, was alle sehen: Daten hochladen, den Zeichenstil bearbeiten und Ebenen löschen. Geben Sie den Admin-Schlüssel ein, mit dem der Server gestartet wurde.',
    'login.open': 'Dieser Server hat keinen Admin-Schlüssel: Änderungen werden nur von diesem Computer angenommen.',
    'login.submit': 'Anmelden',
    'login.cancel': 'Abbrechen',
    'login.wrong': 'Dieser Schlüssel wurde nicht angenommen: {reason}',
    'login.ok': 'Als Planerin oder Planer angemeldet.',
    'login.out': 'Abgemeldet: die Planungswerkzeuge sind ausgeblendet.',
    'login.expired': 'Die Anmeldung gilt nicht mehr; bitte neu anmelden.',
    'conn.connecting': 'verbinde…',
    'conn.open': 'verbunden',
    'conn.retry': 'getrennt — neuer Versuch in {s} s',
    'conn.reconnect': 'Jetzt verbinden',
    'view.label': 'Landschaftsansicht. Ziehen zum Umsehen, W A S D oder Pfeiltasten zum Gehen, Q und E für tiefer oder höher; auf Touchscreens schaut ein Finger, zwei Finger gehen, Spreizen zoomt.',
    'view.waiting': 'Warte auf das erste Bild…',
    'view.rendering': 'Ein scharfes Bild wird gezeichnet…',
    'view.compass': 'Kompass: der Blick geht nach {dir} ({deg}°)',
    'dir.n': 'Norden', 'dir.ne': 'Nordosten', 'dir.e': 'Osten', 'dir.se': 'Südosten',
    'dir.s': 'Süden', 'dir.sw': 'Südwesten', 'dir.w': 'Westen', 'dir.nw': 'Nordwesten',
    'hint.title': 'So bewegen Sie sich',
    'hint.touch': 'Ein Finger: umsehen · zwei Finger: gehen · Spreizen: zoomen · die Knöpfe unten heben den Blick oder zeigen die Planung.',
    'hint.mouse': 'Ziehen: umsehen · W A S D oder Pfeiltasten: gehen · Q / E: tiefer / höher · Mausrad: Gehtempo.',
    'hint.close': 'Verstanden',
    'tool.label': 'Ansicht',
    'tool.walk': 'Gehen',
    'tool.fly': 'Hochfliegen für den Überblick',
    'tool.flyTitle': 'Den Blick anheben und von oben umsehen (F)',
    'tool.bird': 'Vogelperspektive',
    'tool.birdTitle': 'Die Karte von oben, Norden oben (P)',
    'tool.reset': 'Zurück zum Anfang',
    'tool.goPlan': 'Zur Planung',
    'tool.withPlan': 'Mit der Planung',
    'tool.highlight': 'Planung hervorheben',
    'tool.speed': 'Gehtempo',
    'tool.resolution': 'Bildschärfe',
    'res.low': 'grob', 'res.half': 'schnell', 'res.full': 'scharf',
    'tool.screenshot': 'Bild speichern',
    'tool.share': 'Link teilen',
    'tool.rendering': 'Zeichne…',
    'link.label': 'Link zu dieser Ansicht',
    'link.copied': 'Link kopiert.',
    'link.select': 'Kopieren Sie den markierten Link (die Zwischenablage ist nicht verfügbar).',
    'shot.saved': 'Bild mit {w} × {h} Pixeln gespeichert.',
    'shot.failed': 'Das Bild konnte nicht gespeichert werden: {reason}',
    'shot.caption': '{title} — Blick nach {dir}',
    'shot.plan': '{title} — von oben gesehen',
    'shot.withPlan': 'mit der Planung', 'shot.withoutPlan': 'ohne die Planung',
    'shot.width': 'Bildbreite {m} m',
    'shot.distance': 'Augenhöhe {h} m über dem Boden',
    'shot.credit': 'Gezeichnet mit landsketch',
    'welcome.label': 'Über diesen Ort',
    'welcome.controls': 'So sehen Sie sich um',
    'welcome.c1': 'Gehen: das Bild ziehen zum Umsehen; W A S D oder die Pfeiltasten zum Gehen (am Telefon: zwei Finger).',
    'welcome.c2': 'Hochfliegen für den Überblick, oder die Vogelperspektive zeigt das ganze Gebiet als Karte.',
    'welcome.c3': '„Zur Planung“ bringt Sie dorthin, wo sich etwas ändert; „Mit der Planung“ zeigt die Landschaft mit und ohne sie.',
    'legend.title': 'Was Sie sehen',
    'legend.existing': 'Bestehende Bäume und Sträucher',
    'legend.planned': 'Geplante Bepflanzung',
    'legend.plannedOff': 'Geplante Bepflanzung (jetzt ausgeblendet)',
    'looks.title': 'Darstellung',
    'looks.sketch': 'Federzeichnung',
    'looks.colour': 'Skizze mit Farbe',
    'looks.photo': 'Wie ein Foto',
    'looks.book': 'Bilderbuch',
    'data.title': 'Karten auf der Landschaft',
    'data.none': 'Für diesen Ort sind noch keine Datenkarten veröffentlicht.',
    'map.title': 'Karte',
    'map.label': 'Kleine Karte: Sie sind hier (Punkt), Ihr Blickfeld (Kegel), geplante Flächen (Umriss) und Aussichtspunkte (Quadrate). Tippen, um dorthin zu gehen.',
    'map.here': 'Sie sind hier',
    'msg.notReady': 'Der Server ist noch nicht bereit: {reason}. Laden Sie die Seite gleich neu.',
    'msg.refused': 'Die Ansicht dieses Links wurde abgelehnt ({reason}); es wird die Startansicht gezeigt.',
    'msg.layers': 'Die Datenebenen können nicht geladen werden: {reason}',
    'msg.newLayer': 'Eine neue Datenebene ist verfügbar: „{name}“.',
    'msg.noPlan': 'Diese Szene nennt keine geplante Ebene.',
    'tab.about': 'Über',
    'panel.toggle': 'Bedienfelder',
    'panel.label': 'Bedienung',
    'layer.coverage': 'Deckt {pct} % der Szene ab.',
    'layer.outside': 'Diese Ebene liegt außerhalb der Szene.',
    'layer.goto': 'Zur Ebene',
    'layer.units': 'Einheit: {u}',
    'layer.noUnits': 'keine angegeben',
    'layer.legend': 'Legende von {name}',
    'layer.steps': '{n} Zeitschritte',
    'layer.classes': '{n} Klassen',
    'style.f.visible': 'Diese Ebene zeigen',
    'style.f.photorealism': 'Realismus (Zeichnung → Foto)',
    'style.f.hlp_abstraction': 'Baumkronen vereinfachen',
    'style.f.leaf_size': 'Blattgröße',
    'style.f.leaf_shape': 'Blattform',
    'style.f.contour_threshold': 'Umriss-Detail',
    'style.f.contour_strength': 'Umriss-Dunkelheit',
    'style.f.silhouette_map': 'Strichart der Umrisse',
    'style.f.hatch_map': 'Schraffurmuster',
    'style.f.hatch_brightness': 'Helligkeit der Schraffur',
    'style.f.tone_contrast': 'Kontrast von Licht und Schatten',
    'style.f.color': 'Farbmenge',
    'style.f.color_saturation': 'Farbstärke',
    'style.f.color_abstraction': 'Farben vereinfachen',
    'style.advanced': 'Erweitert',
    'tool.tour': 'Rundgang',
    'tour.start': 'Unser Ausgangspunkt',
    'tour.startCaption': 'Der Ort, wie er heute ist, vom Ausgangspunkt aus.',
    'tour.overview': 'Überblick',
    'tour.overviewCaption': 'Das ganze Gebiet von oben.',
    'tour.plan': 'Die Planung',
    'tour.planCaption': 'Die geplante Bepflanzung aus der Nähe.',
    'tour.step': '{name} ({i} von {n})',
    'meeting.open': 'Sitzung starten',
    'meeting.presenting': 'Sitzung {code}: Sie präsentieren',
    'meeting.following': 'Sitzung {code}: Sie folgen der Präsentation',
    'meeting.detached': 'Sitzung {code}: Sie sehen sich selbst um',
    'meeting.followers': '{n} folgen · Beitritt unter {url}',
    'meeting.detach': 'Selbst umsehen',
    'meeting.rejoin': 'Wieder der Präsentation folgen',
    'meeting.close': 'Sitzung beenden',
    'meeting.ended': 'Die Sitzung ist beendet: {reason}',
    'meeting.qr': 'QR-Code zum Beitritt zur Sitzung {code}',
    'mapping.showAs': 'Auf der Landschaft zeigen als',
    'mapping.none': 'nicht gezeigt',
    'mapping.color': 'Farbe',
    'mapping.hatch_tone': 'dunklere oder hellere Schraffur',
    'mapping.hatch_color': 'farbige Schraffur',
    'mapping.hatch_pattern': 'Schraffurmuster',
    'mapping.silhouette_style': 'Umrissart',
    'mapping.silhouette_density': 'Umrissdichte',
    'mapping.abstraction': 'einfachere oder genauere Pflanzen',
    'style.reset': 'Stil zurücksetzen',
    'confirm.cancel': 'Abbrechen',
    'confirm.delete': 'Löschen',
  },
};

/** The languages offered, with their own names. */
export const LANGUAGES = [['en', 'English'], ['de', 'Deutsch']];

let language = 'en';

/** The chosen language: the stored choice, else the browser's if offered, else English. */
export function initialLanguage(stored, preferred = []) {
  if (stored && STRINGS[stored]) return stored;
  return preferred.map((l) => l.slice(0, 2)).find((l) => STRINGS[l]) ?? 'en';
}

/** The string `key` in the current language with `{name}` placeholders filled from `values`. */
export function t(key, values = {}) {
  const text = STRINGS[language][key] ?? STRINGS.en[key] ?? key;
  return text.replace(/\{(\w+)\}/g, (whole, name) => (name in values ? String(values[name]) : whole));
}

/** The current language code. */
export function currentLanguage() {
  return language;
}

/** Fills every `data-i18n*` element under `root` in the current language. */
export function translate(root = document) {
  for (const node of root.querySelectorAll('[data-i18n]')) node.textContent = t(node.dataset.i18n);
  for (const node of root.querySelectorAll('[data-i18n-label]')) node.setAttribute('aria-label', t(node.dataset.i18nLabel));
  for (const node of root.querySelectorAll('[data-i18n-title]')) node.title = t(node.dataset.i18nTitle);
  for (const node of root.querySelectorAll('[data-i18n-placeholder]')) node.placeholder = t(node.dataset.i18nPlaceholder);
  document.documentElement.lang = language;
}

/** Switches to `code`, keeps the choice and fills the page again. */
export function setLanguage(code) {
  if (!STRINGS[code]) return;
  language = code;
  try {
    localStorage.setItem(STORE_KEY, code);
  } catch {
    // Private mode: the choice lasts for this page.
  }
  translate();
}

/** Picks the language of this visit (stored choice or the browser's). */
export function startLanguage() {
  let stored = null;
  try {
    stored = localStorage.getItem(STORE_KEY);
  } catch {
    // No storage: the browser's language.
  }
  language = initialLanguage(stored, globalThis.navigator?.languages ?? []);
}

/** The compass word of heading `yaw` (degrees clockwise from north). */
export function direction(yaw) {
  const names = ['n', 'ne', 'e', 'se', 's', 'sw', 'w', 'nw'];
  return t(`dir.${names[Math.round((((yaw % 360) + 360) % 360) / 45) % 8]}`);
}
