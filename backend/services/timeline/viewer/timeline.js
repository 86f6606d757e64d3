// The timeline viewer: one robot's or one human's events in time order, shared by the web UI's /timeline page
// and the self-contained HTML file of a timeline (services/timeline/standalone.py). It draws a time ruler (how
// many events when; drag on it to zoom into a window), a list that keeps only its visible rows in the page (a
// window of 100,000 events scrolls as one of a hundred), a playhead the keyboard moves (the current event is
// highlighted, announced to screen readers, and named in the address as #t=<time>), and filters by kind and by
// text. Rows come from the page (a JSON data block) or from whoever mounts it (append, upsert). Every text is
// set as text, never as markup: robots write what these rows say.
(function () {
  "use strict";
  var ROW_HEIGHT = 34; // px; .tl-row's height in timeline.css
  var OVERSCAN = 6; // rows drawn beyond each edge of the visible ones
  var FRESH_MS = 4000; // how long a row that just arrived stays marked
  var BREAK_PX = [56, 76]; // a stretch without events cut out of the ruler: room for its length ("36 days")
  var BREAK_SHARE = 0.15; // of the ruler's width, between those bounds
  var EDGE_PX = 16; // a stretch between the window's edge and its first or last event, cut out: a hatched edge
  var PART_MIN_PX = 12; // a part of the ruler that is one instant still shows its events
  var BREAK_RATIO = 20; // stretches cut out together are each this many times as long as any stretch kept
  var MOST_BREAKS = 4; // a lone event before and after the others, and the window's two edges
  var NUMBER = typeof Intl !== "undefined" ? new Intl.NumberFormat("en") : null;

  function count(n) { return NUMBER ? NUMBER.format(n) : String(n); }

  function element(tag, className, text) {
    var made = document.createElement(tag);
    if (className) made.className = className;
    if (text !== undefined) made.textContent = text;
    return made;
  }

  function pad(n, width) { var s = String(n); while (s.length < width) s = "0" + s; return s; }

  // Times are UTC, as the API writes them: 2026-03-10T09:00:05.25Z.
  function clock(ms, withDate) {
    var d = new Date(ms);
    var time = pad(d.getUTCHours(), 2) + ":" + pad(d.getUTCMinutes(), 2) + ":" + pad(d.getUTCSeconds(), 2) +
      "." + pad(d.getUTCMilliseconds(), 3);
    if (!withDate) return time;
    return d.getUTCFullYear() + "-" + pad(d.getUTCMonth() + 1, 2) + "-" + pad(d.getUTCDate(), 2) + " " + time;
  }

  function Timeline(root) {
    this.root = root;
    this.kinds = (root.getAttribute("data-kinds") || "").split(",").filter(Boolean);
    this.rank = {};
    for (var i = 0; i < this.kinds.length; i++) this.rank[this.kinds[i]] = i;
    this.start = Date.parse(root.getAttribute("data-since") || "");
    this.end = Date.parse(root.getAttribute("data-until") || "");
    this.rows = []; // every event, in time order (then kind order, then arrival)
    this.ids = {}; // id → row: a page that arrives after a live change of its events keeps the change
    this.view = []; // the rows shown: the kinds ticked, the text found, the zoom
    this.counts = {};
    this.hidden = {}; // kinds unticked
    this.terms = [];
    this.zoom = null; // [from, to] in ms, or null
    this.current = null; // the row under the playhead
    this.pendingMoment = null; // a #t= not loaded yet
    this.complete = false;
    this.arrivals = 0;
    this.pool = [];
    this.drawn = {}; // view position → row element
    this.build();
    var self = this;
    window.addEventListener("hashchange", function () { self.followHash(); });
    window.addEventListener("resize", function () { self.redrawRuler(); self.schedule(); });
  }

  Timeline.prototype.build = function () {
    var self = this;
    var root = this.root;
    root.textContent = "";
    var toolbar = element("div", "tl-toolbar");
    var kinds = element("fieldset", "tl-kinds");
    kinds.appendChild(element("legend", "", "Kinds"));
    this.kindBoxes = {};
    this.kindCounts = {};
    this.kinds.forEach(function (kind) {
      var label = element("label", "tl-kind-choice");
      var box = element("input");
      box.type = "checkbox";
      box.checked = true;
      box.value = kind;
      box.addEventListener("change", function () {
        if (box.checked) delete self.hidden[kind]; else self.hidden[kind] = true;
        self.refilter();
      });
      var counted = element("span", "tl-kind-count", "0");
      label.appendChild(box);
      label.appendChild(document.createTextNode(" " + kind + " "));
      label.appendChild(counted);
      kinds.appendChild(label);
      self.kindBoxes[kind] = box;
      self.kindCounts[kind] = counted;
    });
    toolbar.appendChild(kinds);
    var find = element("label", "tl-find", "Find ");
    this.search = element("input");
    this.search.type = "search";
    this.search.placeholder = "words in the sentences";
    var typing = null;
    this.search.addEventListener("input", function () {
      window.clearTimeout(typing);
      typing = window.setTimeout(function () {
        self.terms = self.search.value.toLowerCase().split(/\s+/).filter(Boolean);
        self.refilter();
      }, 120);
    });
    find.appendChild(this.search);
    toolbar.appendChild(find);
    this.shown = element("span", "tl-shown muted");
    toolbar.appendChild(this.shown);
    this.unzoom = element("button", "secondary tl-unzoom", "Show the whole window");
    this.unzoom.type = "button";
    this.unzoom.hidden = true;
    this.unzoom.addEventListener("click", function () { self.setZoom(null); });
    toolbar.appendChild(this.unzoom);
    root.appendChild(toolbar);

    // The ruler: how many events when, the zoomed window (drag to choose one), the playhead. The keyboard has
    // its own ways to zoom ([ and ] in the list), so the drawing is left out of the accessibility tree.
    this.ruler = element("div", "tl-ruler");
    this.ruler.setAttribute("aria-hidden", "true");
    this.density = element("canvas", "tl-density");
    this.brush = element("div", "tl-brush");
    this.brush.hidden = true;
    this.playhead = element("div", "tl-playhead");
    this.playhead.hidden = true;
    this.ticks = element("div", "tl-ticks");
    this.breaks = element("div", "tl-breaks");
    this.ruler.appendChild(this.density);
    this.ruler.appendChild(this.breaks);
    this.ruler.appendChild(this.brush);
    this.ruler.appendChild(this.playhead);
    this.ruler.appendChild(this.ticks);
    root.appendChild(this.ruler);
    this.bindRuler();

    var help = element("p", "tl-help muted",
      "In the list: ↑ ↓ move between events, Page Up/Down by a screen, Home/End to the ends, Enter explains the " +
      "current event, G shows it in the graph, [ and ] zoom from or to it, Esc shows the whole window.");
    help.id = (root.id || "timeline") + "-help";
    root.appendChild(help);
    this.list = element("div", "tl-list");
    this.list.tabIndex = 0;
    this.list.setAttribute("role", "region");
    this.list.setAttribute("aria-label", "Events in time order");
    this.list.setAttribute("aria-describedby", help.id);
    this.canvas = element("div", "tl-canvas");
    this.list.appendChild(this.canvas);
    this.empty = element("p", "tl-empty empty", "No events in this window.");
    this.empty.hidden = true;
    this.list.appendChild(this.empty);
    root.appendChild(this.list);
    this.list.addEventListener("scroll", function () { self.schedule(); });
    this.list.addEventListener("keydown", function (event) { self.key(event); });
    this.canvas.addEventListener("click", function (event) {
      var row = event.target.closest ? event.target.closest(".tl-row") : null;
      if (!row || event.target.closest("a")) return;
      self.select(Number(row.getAttribute("data-position")), false);
      self.list.focus({ preventScroll: true });
    });

    // The current event, with links a keyboard reaches, and what screen readers hear as the playhead moves.
    this.panel = element("div", "tl-current");
    this.panel.hidden = true;
    root.appendChild(this.panel);
    this.announcer = element("p", "visually-hidden");
    this.announcer.setAttribute("aria-live", "polite");
    root.appendChild(this.announcer);
  };

  // --- rows ------------------------------------------------------------------------------------------------

  Timeline.prototype.prepare = function (row) {
    row._t = Date.parse(row.time);
    if (isNaN(row._t)) row._t = Infinity;
    row._rank = this.rank[row.kind] === undefined ? this.kinds.length : this.rank[row.kind];
    row._n = this.arrivals++;
    row._text = (row.sentence + " " + row.kind + " " + row.time).toLowerCase();
    return row;
  };

  function before(a, b) {
    if (a._t !== b._t) return a._t < b._t;
    if (a._rank !== b._rank) return a._rank < b._rank;
    return a._n < b._n;
  }

  // Where `row` goes among `rows` kept in order: after every row before it.
  function place(rows, row) {
    var low = 0, high = rows.length;
    while (low < high) {
      var middle = (low + high) >> 1;
      if (before(rows[middle], row)) low = middle + 1; else high = middle;
    }
    return low;
  }

  Timeline.prototype.append = function (rows) {
    for (var i = 0; i < rows.length; i++) {
      if (this.ids[rows[i].id]) continue;
      var row = this.prepare(rows[i]);
      this.ids[row.id] = row;
      var last = this.rows[this.rows.length - 1];
      if (!last || !before(row, last)) this.rows.push(row); else this.rows.splice(place(this.rows, row), 0, row);
      this.counts[row.kind] = (this.counts[row.kind] || 0) + 1;
    }
    this.refilter();
    this.reachMoment();
  };

  // The events about `keys` of one kind are now `rows` (none when they left the window): a live change.
  Timeline.prototype.upsert = function (kind, keys, rows) {
    var gone = {};
    keys.forEach(function (key) { gone[key] = true; });
    var known = {};
    var kept = [];
    for (var i = 0; i < this.rows.length; i++) {
      var row = this.rows[i];
      if (row.kind === kind && gone[row.iri]) {
        known[row.id] = true;
        delete this.ids[row.id];
        this.counts[kind] -= 1;
      } else {
        kept.push(row);
      }
    }
    this.rows = kept;
    var now = Date.now();
    for (var j = 0; j < rows.length; j++) {
      var fresh = this.prepare(rows[j]);
      if (!known[fresh.id]) fresh._fresh = now;
      this.ids[fresh.id] = fresh;
      this.rows.splice(place(this.rows, fresh), 0, fresh);
      this.counts[kind] = (this.counts[kind] || 0) + 1;
    }
    this.refilter();
    var self = this;
    window.setTimeout(function () { self.schedule(); }, FRESH_MS + 50);
  };

  Timeline.prototype.clear = function () {
    this.rows = [];
    this.ids = {};
    this.complete = false;
    this.counts = {};
    this.current = null;
    this.refilter();
  };

  Timeline.prototype.finished = function () {
    this.complete = true;
    this.reachMoment();
  };

  Timeline.prototype.shows = function (row) {
    if (this.hidden[row.kind]) return false;
    if (this.zoom && (row._t < this.zoom[0] || row._t > this.zoom[1])) return false;
    for (var i = 0; i < this.terms.length; i++) if (row._text.indexOf(this.terms[i]) < 0) return false;
    return true;
  };

  Timeline.prototype.refilter = function () {
    this.scaled = null; // the rows may have changed: the ruler's breaks with them
    var view = [];
    for (var i = 0; i < this.rows.length; i++) if (this.shows(this.rows[i])) view.push(this.rows[i]);
    this.view = view;
    this.position = this.current ? this.positionOf(this.current) : -1;
    if (this.position < 0) this.current = null;
    var self = this;
    this.kinds.forEach(function (kind) { self.kindCounts[kind].textContent = count(self.counts[kind] || 0); });
    this.shown.textContent = count(view.length) + " of " + count(this.rows.length) + " events shown";
    this.canvas.style.height = view.length * ROW_HEIGHT + "px";
    this.empty.hidden = view.length > 0;
    for (var position in this.drawn) this.release(position);
    this.redrawRuler();
    this.schedule();
    this.showCurrent(false);
  };

  Timeline.prototype.positionOf = function (row) {
    var at = place(this.view, row);
    for (var i = Math.max(0, at - 1); i < this.view.length && i <= at + 1; i++) if (this.view[i] === row) return i;
    return this.view.indexOf(row);
  };

  // --- drawing the visible rows ------------------------------------------------------------------------------

  Timeline.prototype.schedule = function () {
    if (this.frame) return;
    var self = this;
    this.frame = window.requestAnimationFrame(function () { self.frame = null; self.draw(); });
  };

  Timeline.prototype.draw = function () {
    var top = this.list.scrollTop;
    var first = Math.max(0, Math.floor(top / ROW_HEIGHT) - OVERSCAN);
    var last = Math.min(this.view.length - 1, Math.ceil((top + this.list.clientHeight) / ROW_HEIGHT) + OVERSCAN);
    for (var drawn in this.drawn) if (drawn < first || drawn > last) this.release(drawn);
    var withDate = this.spansDays();
    var now = Date.now();
    for (var position = first; position <= last; position++) {
      var row = this.view[position];
      var shown = this.drawn[position] || this.take(position);
      if (shown._row !== row || shown._withDate !== withDate) this.fill(shown, row, withDate);
      shown.classList.toggle("tl-at", row === this.current);
      shown.classList.toggle("fresh", !!row._fresh && now - row._fresh < FRESH_MS);
    }
  };

  Timeline.prototype.take = function (position) {
    var shown = this.pool.pop();
    if (!shown) {
      shown = element("div", "tl-row");
      shown._time = shown.appendChild(element("span", "tl-time"));
      shown._kind = shown.appendChild(element("span", "tl-kind"));
      shown._sentence = shown.appendChild(element("span", "tl-sentence"));
      var links = shown.appendChild(element("span", "tl-links"));
      shown._explain = links.appendChild(element("a", "", "why?"));
      shown._graph = links.appendChild(element("a", "", "graph"));
      shown._explain.tabIndex = -1; // the current event's panel holds the links the keyboard reaches
      shown._graph.tabIndex = -1;
      this.canvas.appendChild(shown);
    }
    shown.hidden = false;
    shown.setAttribute("data-position", position);
    shown.style.transform = "translateY(" + position * ROW_HEIGHT + "px)";
    this.drawn[position] = shown;
    return shown;
  };

  Timeline.prototype.release = function (position) {
    var shown = this.drawn[position];
    delete this.drawn[position];
    shown.hidden = true;
    shown._row = null;
    this.pool.push(shown);
  };

  Timeline.prototype.fill = function (shown, row, withDate) {
    shown._row = row;
    shown._withDate = withDate;
    shown.className = "tl-row tl-is-" + row.kind;
    shown._time.textContent = row._t === Infinity ? row.time : clock(row._t, withDate);
    shown._kind.textContent = row.kind;
    shown._sentence.textContent = row.sentence;
    shown.title = row.sentence;
    link(shown._explain, row.explain, "why? (explain)");
    link(shown._graph, row.graph, "in the graph");
  };

  function link(anchor, href, title) {
    anchor.hidden = !href;
    if (href) anchor.href = href; else anchor.removeAttribute("href");
    anchor.title = title;
  }

  Timeline.prototype.spansDays = function () {
    var from = this.view.length ? this.view[0]._t : 0;
    var to = this.view.length ? this.view[this.view.length - 1]._t : 0;
    return to === Infinity || new Date(from).toISOString().slice(0, 10) !== new Date(to).toISOString().slice(0, 10);
  };

  // --- the playhead ------------------------------------------------------------------------------------------

  Timeline.prototype.key = function (event) {
    var page = Math.max(1, Math.floor(this.list.clientHeight / ROW_HEIGHT) - 1);
    var at = this.position < 0 ? -1 : this.position;
    var moves = { ArrowDown: at + 1, ArrowUp: Math.max(0, at - 1), PageDown: at + page,
      PageUp: Math.max(0, at - page), Home: 0, End: this.view.length - 1 };
    if (event.altKey || event.ctrlKey || event.metaKey) return;
    if (Object.prototype.hasOwnProperty.call(moves, event.key)) {
      event.preventDefault();
      if (this.view.length) this.select(Math.min(this.view.length - 1, moves[event.key]), true);
    } else if (event.key === "Enter" && this.current && this.current.explain) {
      event.preventDefault();
      window.location.href = this.current.explain;
    } else if ((event.key === "g" || event.key === "G") && this.current && this.current.graph) {
      event.preventDefault();
      window.location.href = this.current.graph;
    } else if (event.key === "[" && this.current) {
      this.setZoom([this.current._t, this.zoom ? this.zoom[1] : this.lastTime()]);
    } else if (event.key === "]" && this.current) {
      this.setZoom([this.zoom ? this.zoom[0] : this.firstTime(), this.current._t]);
    } else if (event.key === "Escape" && this.zoom) {
      this.setZoom(null);
    }
  };

  Timeline.prototype.select = function (position, fromKeyboard) {
    if (position < 0 || position >= this.view.length) return;
    this.current = this.view[position];
    this.position = position;
    var top = position * ROW_HEIGHT;
    var list = this.list;
    if (top < list.scrollTop) list.scrollTop = top;
    else if (top + ROW_HEIGHT > list.scrollTop + list.clientHeight) list.scrollTop = top + ROW_HEIGHT - list.clientHeight;
    this.schedule();
    this.showCurrent(true);
    this.remember(fromKeyboard);
  };

  // Bring the current event to the middle of the list (a deep link, a click on the ruler).
  Timeline.prototype.center = function () {
    if (this.position < 0) return;
    this.list.scrollTop = Math.max(0, this.position * ROW_HEIGHT - (this.list.clientHeight - ROW_HEIGHT) / 2);
    this.schedule();
  };

  Timeline.prototype.showCurrent = function (announce) {
    var row = this.current;
    this.panel.hidden = !row;
    this.playhead.hidden = !row;
    if (!row) return;
    this.panel.textContent = "";
    this.panel.appendChild(element("strong", "", "Current event "));
    this.panel.appendChild(element("span", "tl-time", clock(row._t, true)));
    this.panel.appendChild(element("span", "tl-kind", row.kind));
    this.panel.appendChild(element("span", "tl-sentence-full", row.sentence));
    this.panel.appendChild(element("code", "tl-iri", row.iri));
    if (row.explain) {
      var why = this.panel.appendChild(element("a", "", "Why did it happen?"));
      why.href = row.explain;
    }
    if (row.graph) {
      var graph = this.panel.appendChild(element("a", "", "See it in the graph"));
      graph.href = row.graph;
    }
    this.playhead.style.left = this.x(row._t) + "px";
    if (announce) {
      this.announcer.textContent = clock(row._t, true) + ", " + row.kind + ": " + row.sentence + " (" +
        count(this.position + 1) + " of " + count(this.view.length) + ")";
    }
  };

  // The address names the moment under the playhead: a link to it opens there.
  Timeline.prototype.remember = function () {
    var row = this.current;
    if (!row || !window.history || !window.history.replaceState) return;
    window.clearTimeout(this.remembering);
    this.remembering = window.setTimeout(function () {
      window.history.replaceState(null, "", "#t=" + row.time);
    }, 150);
  };

  Timeline.prototype.followHash = function () {
    var found = /(?:^#|&)t=([^&]+)/.exec(window.location.hash);
    if (!found) return;
    var moment = Date.parse(decodeURIComponent(found[1]));
    if (isNaN(moment)) return;
    if (this.current && this.current._t === moment) return; // the address follows the playhead
    this.pendingMoment = moment;
    this.reachMoment();
  };

  // A #t= moment is selected once the rows around it are loaded: the nearest event, scrolled to the middle.
  Timeline.prototype.reachMoment = function () {
    var moment = this.pendingMoment;
    if (moment === null || !this.view.length) return;
    var last = this.rows[this.rows.length - 1];
    if (!this.complete && (!last || last._t < moment)) return;
    this.pendingMoment = null;
    var at = this.nearest(moment);
    this.select(at, false);
    this.center();
    this.showCurrent(true);
  };

  Timeline.prototype.nearest = function (moment) {
    var low = 0, high = this.view.length;
    while (low < high) {
      var middle = (low + high) >> 1;
      if (this.view[middle]._t < moment) low = middle + 1; else high = middle;
    }
    if (low >= this.view.length) return this.view.length - 1;
    if (low > 0 && moment - this.view[low - 1]._t < this.view[low]._t - moment) {
      // The one before is nearer: the first event of its instant.
      var earlier = low - 1;
      while (earlier > 0 && this.view[earlier - 1]._t === this.view[low - 1]._t) earlier -= 1;
      return earlier;
    }
    return low;
  };

  // --- the ruler -----------------------------------------------------------------------------------------

  Timeline.prototype.firstTime = function () {
    if (!isNaN(this.start)) return this.start;
    return this.rows.length ? this.rows[0]._t : 0;
  };

  Timeline.prototype.lastTime = function () {
    if (!isNaN(this.end)) return this.end;
    for (var i = this.rows.length - 1; i >= 0; i--) if (this.rows[i]._t !== Infinity) return this.rows[i]._t;
    return this.firstTime();
  };

  // The ruler's scale: the window's time laid across its width, except that a long stretch without events (a
  // training run weeks before a conversation) is cut out and drawn as a narrow break labelled with its length, so
  // the events spread over the ruler instead of sitting in a sliver of it. A stretch cut out between the window's
  // edge and its first or last event leaves a narrower hatched edge and no part of its own: the ruler spans where
  // the events are. Each part between breaks is linear. Worked out again when the rows or the ruler's width
  // change (refilter forgets it).
  Timeline.prototype.scale = function () {
    var width = this.ruler.clientWidth;
    if (this.scaled && this.scaled.width === width) return this.scaled;
    var first = this.firstTime(), last = this.lastTime();
    var cuts = this.quietStretches(first, last);
    if (!cuts.length) {
      this.scaled = { width: width, parts: [{ from: first, to: last, left: 0, right: width }] };
      return this.scaled;
    }
    var breakPx = Math.round(Math.min(BREAK_PX[1], Math.max(BREAK_PX[0], BREAK_SHARE * width)));
    var parts = [];
    var from = first;
    cuts.forEach(function (cut) {
      cut.width = cut.lead || cut.trail ? EDGE_PX : breakPx;
      parts.push({ from: from, to: cut.from, edge: !!cut.lead });
      from = cut.to;
    });
    parts.push({ from: from, to: Math.max(from, last), edge: !!cuts[cuts.length - 1].trail });
    var inner = parts.filter(function (part) { return !part.edge; });
    var breaks = cuts.reduce(function (sum, cut) { return sum + cut.width; }, 0);
    var spread = Math.max(0, width - breaks - inner.length * PART_MIN_PX);
    var drawn = inner.reduce(function (sum, part) { return sum + (part.to - part.from); }, 0);
    var left = 0;
    parts.forEach(function (part, n) {
      part.left = left;
      var share = drawn > 0 ? (part.to - part.from) / drawn : 1 / inner.length;
      part.right = part.edge ? left : left + PART_MIN_PX + spread * share;
      left = part.right + (n < cuts.length ? cuts[n].width : 0);
    });
    this.scaled = { width: width, parts: parts };
    return this.scaled;
  };

  // The stretches without events to cut out of the ruler, in time order: of the longest few (between events, and
  // between the window's edges and its first and last events), longest first, each while it is at least as long
  // as the time left on the ruler once it is out (two events an hour apart keep their hour: it is the whole
  // story; a minute's pause in a conversation of ten keeps its place). Several stretches of about one
  // length, that one at a time would not be cut, go together when each is at least as long as what is left and
  // many times as long as any stretch left in: a window of months around a training run and a conversation.
  Timeline.prototype.quietStretches = function (first, last) {
    var longest = []; // the MOST_BREAKS + 1 longest stretches, longest first
    var previous = first;
    var lead = true;
    function gap(to, trail) {
      var kept = longest[MOST_BREAKS];
      if (to - previous > (kept ? kept.to - kept.from : 0)) { // rare: most gaps between events are short
        longest.push({ from: previous, to: to, lead: lead, trail: trail });
        longest.sort(function (a, b) { return (b.to - b.from) - (a.to - a.from); });
        if (longest.length > MOST_BREAKS + 1) longest.pop();
      }
      previous = Math.max(previous, to);
      lead = false;
    }
    for (var i = 0; i < this.rows.length; i++) if (this.rows[i]._t !== Infinity) gap(this.rows[i]._t, false);
    gap(last, true);
    var cut = 0, out = 0, oneByOne = true;
    for (var k = 1; k <= Math.min(MOST_BREAKS, longest.length); k++) {
      var shortest = longest[k - 1].to - longest[k - 1].from;
      out += shortest;
      var left = last - first - out;
      var keptLongest = longest[k] ? longest[k].to - longest[k].from : 0;
      var longer = left > 0 && shortest >= left;
      oneByOne = oneByOne && longer;
      if (oneByOne || (longer && shortest >= BREAK_RATIO * keptLongest)) cut = k;
    }
    return longest.slice(0, cut).sort(function (a, b) { return a.from - b.from; });
  };

  Timeline.prototype.x = function (t) {
    var scale = this.scale(), parts = scale.parts;
    for (var i = 0; i < parts.length; i++) {
      var part = parts[i];
      if (t < part.from) {
        if (i === 0) return 0;
        var before = parts[i - 1]; // within a break: where in the quiet stretch
        return before.right + (part.left - before.right) * (t - before.to) / (part.from - before.to);
      }
      if (t <= part.to) {
        if (part.to === part.from) return (part.left + part.right) / 2;
        return part.left + (part.right - part.left) * (t - part.from) / (part.to - part.from);
      }
    }
    return scale.width;
  };

  Timeline.prototype.timeAt = function (x) {
    var parts = this.scale().parts;
    for (var i = 0; i < parts.length; i++) {
      var part = parts[i];
      if (x < part.left && i > 0) {
        var before = parts[i - 1];
        return before.to + (part.from - before.to) * (x - before.right) / (part.left - before.right);
      }
      if (x <= part.right) {
        return part.from + (part.to - part.from) * Math.max(0, x - part.left) / Math.max(1, part.right - part.left);
      }
    }
    return parts[parts.length - 1].to;
  };

  // A quiet stretch's length, as the break in the ruler names it.
  function lasting(ms) {
    var units = [[86400000, "days"], [3600000, "h"], [60000, "min"], [1000, "s"]];
    for (var i = 0; i < units.length; i++) {
      if (ms >= 2 * units[i][0]) return Math.round(ms / units[i][0]) + " " + units[i][1];
    }
    return ms + " ms";
  }

  Timeline.prototype.redrawRuler = function () {
    var self = this;
    if (this.rulerFrame) return;
    this.rulerFrame = window.requestAnimationFrame(function () { self.rulerFrame = null; self.drawRuler(); });
  };

  Timeline.prototype.drawRuler = function () {
    var width = this.ruler.clientWidth, height = this.density.clientHeight || 40;
    var ratio = window.devicePixelRatio || 1;
    this.density.width = Math.max(1, Math.round(width * ratio));
    this.density.height = Math.max(1, Math.round(height * ratio));
    var context = this.density.getContext("2d");
    if (!context) return;
    var columns = this.density.width;
    var counts = new Uint32Array(columns);
    var most = 0;
    // The events of the kinds ticked and the words found, whatever the zoom: the ruler is the whole window.
    for (var i = 0; i < this.rows.length; i++) {
      var row = this.rows[i];
      if (row._t === Infinity || this.hidden[row.kind]) continue;
      if (this.terms.length && !this.matches(row)) continue;
      var column = Math.min(columns - 1, Math.max(0, Math.floor(this.x(row._t) * ratio)));
      counts[column] += 1;
      if (counts[column] > most) most = counts[column];
    }
    context.clearRect(0, 0, this.density.width, this.density.height);
    context.fillStyle = "#2f5fd0";
    var scale = Math.log(most + 1) || 1;
    for (var c = 0; c < columns; c++) {
      if (!counts[c]) continue;
      var bar = Math.max(ratio, Math.log(counts[c] + 1) / scale * this.density.height);
      context.fillRect(c, this.density.height - bar, 1, bar);
    }
    this.drawTicks(width);
    this.drawBreaks();
    this.drawBrush();
    if (this.current) this.playhead.style.left = this.x(this.current._t) + "px";
  };

  Timeline.prototype.matches = function (row) {
    for (var i = 0; i < this.terms.length; i++) if (row._text.indexOf(this.terms[i]) < 0) return false;
    return true;
  };

  // Ticks in each part of the ruler (none on a hatched edge). The first time of each part and the ruler's last
  // are placed first, so a lone event drawn apart keeps its date; ticks between them fill the room left. A label
  // that would meet another is left out, and one that would run past the ruler's end ends there instead.
  Timeline.prototype.drawTicks = function (width) {
    this.ticks.textContent = "";
    if (!this.rows.length && isNaN(this.start)) return;
    var from = this.firstTime(), to = this.lastTime();
    var withDate = to - from > 86400000 || new Date(from).getUTCDate() !== new Date(to).getUTCDate();
    var parts = this.scale().parts.filter(function (part) { return !part.edge; });
    var marks = [];
    parts.forEach(function (part, n) {
      var count = part.to > part.from ? Math.max(1, Math.floor((part.right - part.left) / (withDate ? 300 : 180))) : 0;
      if (!count) marks.push({ t: part.from, x: (part.left + part.right) / 2, key: true });
      for (var i = 0; i < count; i++) {
        var share = i / count;
        marks.push({
          t: part.from + (part.to - part.from) * share, x: part.left + (part.right - part.left) * share, key: i === 0,
        });
      }
      if (n === parts.length - 1 && count) marks.push({ t: part.to, x: part.right, key: true });
    });
    var ordered = marks.filter(function (mark) { return mark.key; })
      .concat(marks.filter(function (mark) { return !mark.key; }));
    var kept = [];
    for (var m = 0; m < ordered.length; m++) {
      var mark = ordered[m];
      var tick = this.ticks.appendChild(element("span", "tl-tick", clock(mark.t, withDate).replace(/\.\d+$/, "")));
      tick.style.left = mark.x + "px";
      var start = mark.x, size = tick.offsetWidth;
      if (start + size > width) {
        tick.classList.add("tl-tick-last");
        start -= size;
      }
      var meets = kept.some(function (other) { return start < other.end + 8 && start + size + 8 > other.start; });
      if (meets) { this.ticks.removeChild(tick); continue; }
      kept.push({ start: start, end: start + size, tick: tick });
    }
    var ticks = this.ticks;
    kept.sort(function (a, b) { return a.start - b.start; }).forEach(function (one) { ticks.appendChild(one.tick); });
  };

  // Where the ruler leaves out a stretch without events: a hatched gap that says how long the stretch is; at the
  // window's edge, a narrower one that says it in its title.
  Timeline.prototype.drawBreaks = function () {
    this.breaks.textContent = "";
    var parts = this.scale().parts;
    for (var i = 1; i < parts.length; i++) {
      var length = lasting(parts[i].from - parts[i - 1].to);
      var edge = parts[i - 1].edge ? " before the first event" : parts[i].edge ? " after the last event" : "";
      var gap = this.breaks.appendChild(element("div", edge ? "tl-break tl-break-edge" : "tl-break"));
      gap.style.left = parts[i - 1].right + "px";
      gap.style.width = parts[i].left - parts[i - 1].right + "px";
      gap.title = length + " without events" + edge + ", left out of the ruler";
      if (!edge) gap.appendChild(element("span", "tl-break-label", length));
    }
    this.root.setAttribute("data-ruler-breaks", String(parts.length - 1));
  };

  Timeline.prototype.drawBrush = function () {
    this.brush.hidden = !this.zoom;
    this.unzoom.hidden = !this.zoom;
    if (!this.zoom) return;
    var left = this.x(this.zoom[0]), right = this.x(this.zoom[1]);
    this.brush.style.left = left + "px";
    this.brush.style.width = Math.max(2, right - left) + "px";
  };

  Timeline.prototype.setZoom = function (zoom) {
    if (zoom && zoom[1] < zoom[0]) zoom = [zoom[1], zoom[0]];
    this.zoom = zoom;
    this.refilter();
    if (this.current) this.center();
    this.announcer.textContent = zoom
      ? "Zoomed to " + clock(zoom[0], true) + " – " + clock(zoom[1], true) + ": " + count(this.view.length) + " events"
      : "The whole window: " + count(this.view.length) + " events";
  };

  // Drag on the ruler to zoom into a window; a click moves the playhead to the event nearest that time.
  Timeline.prototype.bindRuler = function () {
    var self = this;
    var from = null;
    function offset(event) { return event.clientX - self.ruler.getBoundingClientRect().left; }
    this.ruler.addEventListener("pointerdown", function (event) {
      from = offset(event);
      self.ruler.setPointerCapture(event.pointerId);
    });
    this.ruler.addEventListener("pointermove", function (event) {
      if (from === null) return;
      var to = offset(event);
      self.brush.hidden = false;
      self.brush.style.left = Math.min(from, to) + "px";
      self.brush.style.width = Math.abs(to - from) + "px";
    });
    this.ruler.addEventListener("pointerup", function (event) {
      if (from === null) return;
      var to = offset(event), start = from;
      from = null;
      if (Math.abs(to - start) > 4) {
        self.setZoom([self.timeAt(Math.min(start, to)), self.timeAt(Math.max(start, to))]);
      } else {
        self.drawBrush();
        if (self.view.length) {
          self.select(self.nearest(self.timeAt(to)), false);
          self.center();
          self.list.focus({ preventScroll: true });
        }
      }
    });
  };

  // --- mounting ------------------------------------------------------------------------------------------------

  function mount(root) {
    var timeline = new Timeline(root);
    var data = root.getAttribute("data-rows");
    if (data) {
      var block = document.getElementById(data);
      timeline.append(block ? JSON.parse(block.textContent) : []);
      timeline.finished();
    }
    timeline.followHash();
    return timeline;
  }

  window.SEGBTimeline = { mount: mount };
  var own = document.querySelectorAll("[data-timeline][data-rows]");
  for (var i = 0; i < own.length; i++) mount(own[i]);
})();
