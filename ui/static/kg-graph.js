/* Knowledge-graph explorer: draws /kg-graph/data with cytoscape.js (vendored), opens node details from
 * /kg-graph/resource, merges neighbourhoods on demand. Every text from the graph is set with textContent:
 * robot-supplied strings never become markup.
 *
 * Readable at first sight: every lane in use has nodes in view and is named on a band that holds its nodes,
 * robots, humans and messages carry labels at the starting zoom (the others on hover, keyboard focus or when
 * zoomed in), "other" nodes (property values, observations, parameters) are folded away behind a toggle, and
 * the drawing starts at a zoom where labels can be read. Edges to robots, humans and models (hubs standing
 * outside time, with an edge to much of the drawing) are faint, drawn under the others and unlabelled; a node
 * hovered, focused or selected lights its edges up. An edge's label is drawn only where it covers no node and
 * no other label (lit edges first), so zooming in shows more of them and never a pile. Fit fills the box:
 * lanes move apart in a tall box, time columns in a wide one. The drawing takes keyboard focus: arrows move
 * between nodes, Enter opens one. */
(function () {
  "use strict";

  var KIND_COLOURS = {
    robot: "#12203f", human: "#e6a700", "shared-event": "#7b3fb5", activity: "#2f5fd0", message: "#00838f",
    emotion: "#c62828", state: "#2e7d32", model: "#8d6e63", other: "#9aa3b5"
  };
  // Lanes from top to bottom; within a lane, time runs left to right.
  var LANES = ["robot", "human", "shared-event", "activity", "message", "emotion", "state", "model", "other"];
  var LANE_NAMES = {
    robot: "Robots", human: "Humans", "shared-event": "Shared events", activity: "Activities", message: "Messages",
    emotion: "Emotions", state: "States", model: "Models", other: "Other"
  };
  // A lane: up to SUB_ROWS rows SUB_ROW apart, then room for its name above the next lane (model units).
  var LANE_HEIGHT = 110, SUB_ROW = 26, SUB_ROWS = 3, STEP = 42, NODE_SIZE = 18;
  // A lane's band begins this far below the previous lane's last row (model units); its name sits above its rows.
  var BAND_MARGIN = 10, ROWS_SPAN = (SUB_ROWS - 1) * SUB_ROW + NODE_SIZE;
  var MAX_LANE_STRETCH = 4; // Fit may stretch lanes apart up to this much to fill a tall box
  var MAX_COLUMN_STRETCH = 3; // and time columns apart up to this much to fill a wide one
  var FIT_PADDING = 30; // pixels left around the whole drawing
  var FIRST_ZOOM = 1.5; // a small drawing starts no larger than this
  // Room a labelled node needs in its row before the next one (model units); others need one time step.
  var GAP = { robot: 170, human: 170, message: 170, model: 2 * STEP };
  // Robots, humans and models stand outside time, in columns where their lanes begin.
  var STANDING = { robot: true, human: true, model: true };
  var LABELLED = { robot: true, human: true, message: true }; // labelled at the starting zoom, right of the node
  var READABLE_ZOOM = 0.75; // below this the labels of robots, humans and messages are too small to read
  var EDGE_LABEL_ZOOM = 0.9; // below this edges' labels (9 units) are too small to read: none is drawn
  var NODE_LABEL_ZOOM = 1.25; // nor, below this, the labels (11 units) of activities, emotions, states…
  var LARGE = 400; // above this many nodes, drawing favours speed over detail (straight edges, no edge labels)
  var ARROWS = { ArrowRight: [1, 0], ArrowLeft: [-1, 0], ArrowDown: [0, 1], ArrowUp: [0, -1] };

  var container = document.getElementById("graph");
  // WebGL drawing (cytoscape 3.31+) is opt-in: software GL in headless or GPU-less browsers is slower than canvas.
  var WEBGL = new URLSearchParams(window.location.search).get("renderer") === "webgl";
  var panel = document.getElementById("graph-panel");
  var stats = document.getElementById("graph-stats");
  var errorBox = document.getElementById("graph-error");
  var lanesBox = document.getElementById("graph-lanes");
  var showOther = document.getElementById("graph-show-other");
  var otherCount = document.getElementById("graph-other-count");
  var announce = document.getElementById("graph-announce");
  var list = document.getElementById("graph-list");
  var listBody = document.getElementById("graph-list-body");
  var prefixes = JSON.parse(container.dataset.prefixes || "{}");
  var started = performance.now();
  var fetchedAt = 0;
  var cy = null;
  var truncated = false;
  var large = false; // thousands of nodes: drawing favours speed over detail
  var focused = null;
  var laneItems = {};
  var laneSlots = {}; // kind → its place from the top among the lanes drawn now
  var laneHalves = {}; // kind → half the height of its tallest node (model units)
  var laneHeight = LANE_HEIGHT;
  var columnScale = 1; // time columns' spread: Fit widens it in a wide box
  var labelsAt = -1; // the labelLevel() the labels were last placed at
  var viewNote = "";

  function fetchJson(url) {
    return fetch(url, { credentials: "same-origin", headers: { Accept: "application/json" } }).then(function (r) {
      return r.json().catch(function () { return {}; }).then(function (body) {
        if (!r.ok) { throw new Error(body.detail || (r.status + " " + r.statusText)); }
        return body;
      });
    });
  }

  function showError(error) {
    errorBox.textContent = "The graph could not be loaded: " + error.message;
    errorBox.hidden = false;
    stats.textContent = "";
  }

  function el(tag, text, className) {
    var node = document.createElement(tag);
    if (text !== undefined && text !== null) { node.textContent = String(text); }
    if (className) { node.className = className; }
    return node;
  }

  /* `prefix:local` for an IRI in a known vocabulary, else the IRI. */
  function compact(iri) {
    var text = String(iri);
    var names = Object.keys(prefixes);
    for (var i = 0; i < names.length; i++) {
      var namespace = prefixes[names[i]];
      if (text.indexOf(namespace) === 0 && text.length > namespace.length) {
        return names[i] + ":" + text.slice(namespace.length);
      }
    }
    return text;
  }

  /* A resource's name as the API gives it, unless that is only its IRI's last part made of a generated id
   * (`implementation_8427…`, `observation-0417…`): then the words around the id, or "unnamed". */
  function readable(iri, label) {
    var text = String(label || "");
    var tail = String(iri).replace(/[\/#]+$/, "").split(/[\/#]/).pop();
    if (text && text !== tail) { return text; }
    if (!/[0-9a-f]{12,}/i.test(tail) && !/^(human|robot)_/.test(tail)) { return tail || "unnamed"; }
    return tail.replace(/[-_]?[0-9a-f]{12,}/gi, "").replace(/[-_]+/g, " ").trim() || "unnamed";
  }

  /* Places: timed nodes by the rank of their time among the distinct times (nodes of one moment share a
   * column); robots, humans and models at the left, where their lanes begin, in columns of SUB_ROWS; other
   * untimed nodes at the mean of their placed neighbours, else after the last time; then each lane spreads its
   * nodes over a few sub-rows so that neither nodes nor labels overlap. `{id: {x, row}}`: the rows become
   * heights in arrange(). Linear in nodes and edges (plus sorting the times). */
  function layout(nodes, edges, anchor) {
    var x = {}, adjacency = {};
    edges.forEach(function (e) {
      (adjacency[e.source] = adjacency[e.source] || []).push(e.target);
      (adjacency[e.target] = adjacency[e.target] || []).push(e.source);
    });
    var times = {};
    nodes.forEach(function (n) { if (n.time) { times[n.time] = true; } });
    var rank = {};
    Object.keys(times).sort().forEach(function (time, i) { rank[time] = i; });
    var offset = anchor ? anchor.x : 0;
    nodes.forEach(function (n) { if (n.time) { x[n.id] = offset + rank[n.time] * STEP; } });
    var placed = {};
    nodes.forEach(function (n) {
      if (!anchor && !n.time && STANDING[n.kind]) {
        var column = Math.floor((placed[n.kind] = (placed[n.kind] || 0) + 1) / SUB_ROWS - 1e-9);
        x[n.id] = offset - STEP - (column + 1) * (GAP[n.kind] || GAP.robot);
      }
    });
    for (var pass = 0; pass < 2; pass++) {
      nodes.forEach(function (n) {
        if (x[n.id] !== undefined) { return; }
        var xs = (adjacency[n.id] || []).map(function (m) { return x[m]; }).filter(function (v) { return v !== undefined; });
        if (xs.length) { x[n.id] = xs.reduce(function (a, b) { return a + b; }, 0) / xs.length; }
      });
    }
    var last = Math.max.apply(null, [offset].concat(Object.keys(x).map(function (id) { return x[id]; })));
    nodes.forEach(function (n) { if (x[n.id] === undefined) { x[n.id] = last + STEP; } }); // the packing spreads them
    var byLane = {};
    nodes.forEach(function (n) { (byLane[n.kind] = byLane[n.kind] || []).push(n); });
    var positions = {};
    Object.keys(byLane).forEach(function (kind) {
      var gap = STANDING[kind] ? GAP[kind] || GAP.robot : GAP[kind] || STEP, rows = SUB_ROWS;
      var lastX = [];
      for (var r = 0; r < rows; r++) { lastX.push(-Infinity); }
      byLane[kind].sort(function (a, b) { return x[a.id] - x[b.id]; });
      byLane[kind].forEach(function (n) {
        var want = x[n.id], row = 0, best = 0;
        for (row = 0; row < rows; row++) {
          if (want - lastX[row] >= gap) { break; }
          if (lastX[row] < lastX[best]) { best = row; }
        }
        if (row === rows) { row = best; want = lastX[best] + gap; }
        lastX[row] = want;
        positions[n.id] = { x: want, row: row };
      });
    });
    return positions;
  }

  function nodeElement(n, place) {
    var node = { group: "nodes", data: { id: n.id, label: n.label, kind: n.kind, time: n.time || "", row: place.row,
      x0: place.x }, position: { x: columnX(place.x), y: place.row * SUB_ROW } };
    if (n.kind === "other" && !showOther.checked) { node.classes = "folded"; }
    return node;
  }

  function edgeElement(e) {
    return { group: "edges", data: { id: e.id, source: e.source, target: e.target, label: e.label } };
  }

  /* A node's x from its place in time: Fit spreads the time columns (x ≥ 0) in a wide box; the columns of the
   * robots, humans and models left of them keep the room their labels need. */
  function columnX(x0) { return x0 > 0 ? x0 * columnScale : x0; }

  /* Lanes top to bottom, only those with a node drawn, each laneHeight below the last: a kind filtered out or
   * folded leaves no empty band. Nodes keep their rows and places in time; only the spread changes. */
  function arrange() {
    var slot = 0, drawn = {};
    shown().forEach(function (n) { drawn[n.data("kind")] = true; });
    laneSlots = {};
    LANES.forEach(function (kind) { if (drawn[kind]) { laneSlots[kind] = slot++; } });
    laneHalves = {};
    cy.batch(function () {
      cy.nodes().forEach(function (n) {
        var kind = n.data("kind"), lane = laneSlots[kind], row = n.data("row");
        n.position({ x: columnX(n.data("x0")), y: (lane === undefined ? slot : lane) * laneHeight + row * SUB_ROW });
        if (row === 0) { // the first row's top, as cytoscape.js bounds it: where the lane's name must end
          laneHalves[kind] = Math.max(laneHalves[kind] || 0, n.outerHeight() / 2 + 1);
        }
      });
    });
    lightEdges();
    if (large) { placeLabels(); } // the labels have moved (lightEdges places them only in a small drawing)
  }

  /* A lane's band (model units): from just below the previous lane's last row to just below its own. */
  function laneBand(slot) {
    var top = slot * laneHeight - NODE_SIZE / 2 - (laneHeight - ROWS_SPAN) + BAND_MARGIN;
    return { top: top, bottom: top + laneHeight };
  }

  /* Edges of the hubs (robots, humans, models) are faint: each reaches much of the drawing. */
  function markHubEdges(edges) {
    edges.forEach(function (e) {
      if (STANDING[e.source().data("kind")] || STANDING[e.target().data("kind")]) { e.addClass("hub"); }
    });
  }

  /* The edges of the nodes hovered, focused or selected are lit; then the labels are placed again (in a large
   * drawing only when the zoom or the places change: a hovered node shows its own label anyway). */
  function lightEdges() {
    var lit = cy.nodes(".hover, .focused, :selected").connectedEdges();
    cy.edges(".lit").difference(lit).removeClass("lit");
    lit.addClass("lit");
    if (!large) { placeLabels(); }
  }

  /* How many kinds of label the zoom lets be read: 0 only those of robots, humans and messages, 1 edges' too
   * (none in a large drawing), 2 every node's too. */
  function labelLevel() {
    var zoom = cy.zoom();
    return zoom >= NODE_LABEL_ZOOM ? 2 : zoom >= EDGE_LABEL_ZOOM && !large ? 1 : 0;
  }

  /* Which labels are drawn: those of robots, humans, messages and of nodes hovered, focused, selected or just
   * published always; then, once the zoom lets them be read, the other nodes' and then the edges' (the lit
   * ones first, never a faint hub's), each only where it covers no node and no label already placed. The boxes
   * are in model units, so what fits at one zoom fits at all: zooming in shows more and never a pile. */
  function placeLabels() {
    var level = labelLevel(), named = [], labelled = [];
    labelsAt = level;
    var nodes = level > 0 ? shown() : cy.collection(), taken = boxGrid();
    nodes.forEach(function (n) {
      taken.add(nodeBox(n));
      if (alwaysLabelled(n)) { taken.add(nodeLabelBox(n)); }
    });
    if (level >= 2) {
      nodes.forEach(function (n) {
        if (alwaysLabelled(n)) { return; }
        var box = nodeLabelBox(n);
        if (!taken.hits(box)) { taken.add(box); named.push(n); }
      });
    }
    if (level >= 1 && !large) {
      cy.edges(".lit").union(cy.edges().not(".hub")).forEach(function (e) {
        if (e.source().hasClass("folded") || e.target().hasClass("folded")) { return; }
        var box = labelBox(e);
        if (!taken.hits(box)) { taken.add(box); labelled.push(e); }
      });
    }
    cy.batch(function () {
      cy.elements(".named, .labelled").removeClass("named labelled");
      cy.collection(named).addClass("named");
      cy.collection(labelled).addClass("labelled");
    });
  }

  /* Robots, humans and messages, and nodes hovered, focused, selected or just published: labelled at any zoom. */
  function alwaysLabelled(node) {
    return LABELLED[node.data("kind")] || node.selected() || node.hasClass("hover") || node.hasClass("focused") ||
      node.hasClass("fresh");
  }

  /* Boxes kept in square cells, so that asking whether a box hits one already kept reads only its cells. */
  function boxGrid() {
    var CELL = 64, cells = {};
    function each(box, visit) {
      for (var i = Math.floor(box.x1 / CELL); i <= Math.floor(box.x2 / CELL); i++) {
        for (var j = Math.floor(box.y1 / CELL); j <= Math.floor(box.y2 / CELL); j++) {
          if (visit(i + ":" + j)) { return true; }
        }
      }
      return false;
    }
    return {
      add: function (box) { each(box, function (key) { (cells[key] = cells[key] || []).push(box); }); },
      hits: function (box) {
        return each(box, function (key) { return (cells[key] || []).some(function (b) { return overlap(box, b); }); });
      }
    };
  }

  var measure = document.createElement("canvas").getContext("2d"), widths = {};

  function textWidth(element, text) {
    var font = element.pstyle("font-weight").strValue + " " + element.pstyle("font-size").pfValue + "px " +
      element.pstyle("font-family").strValue, key = font + "\n" + text;
    if (widths[key] === undefined) {
      measure.font = font;
      widths[key] = measure.measureText(String(text)).width;
    }
    return widths[key];
  }

  /* Where an edge's label is drawn (model units): its text's width along the edge, centred on the edge's middle
   * (a parallel edge bends away: cytoscape.js gives that point) and turned with it, as the box around that.
   * Measured here, not asked of cytoscape.js, which sizes a label only once it has been drawn on screen. */
  function labelBox(edge) {
    var size = edge.pstyle("font-size").pfValue;
    var half = { w: textWidth(edge, edge.data("label")) / 2 + 4, h: size / 2 + 3 };
    var from = edge.source().position(), to = edge.target().position(), middle = edge.midpoint();
    var angle = Math.atan2(to.y - from.y, to.x - from.x);
    var cos = Math.abs(Math.cos(angle)), sin = Math.abs(Math.sin(angle));
    var dx = half.w * cos + half.h * sin, dy = half.w * sin + half.h * cos;
    return { x1: middle.x - dx, x2: middle.x + dx, y1: middle.y - dy, y2: middle.y + dy };
  }

  /* A node's shape (model units), with a little room around it. */
  function nodeBox(node) {
    var at = node.position(), w = node.width() / 2 + 3, h = node.height() / 2 + 3;
    return { x1: at.x - w, x2: at.x + w, y1: at.y - h, y2: at.y + h };
  }

  /* Where a node's label is drawn (model units): right of a robot, human or message, else below the node; cut
   * at its text-max-width. */
  function nodeLabelBox(node) {
    var at = node.position(), size = node.pstyle("font-size").pfValue;
    var width = Math.min(textWidth(node, node.data("label")), node.pstyle("text-max-width").pfValue) + 4;
    if (node.pstyle("text-halign").strValue === "right") {
      var left = at.x + node.width() / 2 + node.pstyle("text-margin-x").pfValue;
      return { x1: left, x2: left + width, y1: at.y - size / 2 - 2, y2: at.y + size / 2 + 2 };
    }
    var top = at.y + node.height() / 2 + node.pstyle("text-margin-y").pfValue;
    return { x1: at.x - width / 2, x2: at.x + width / 2, y1: top, y2: top + size + 4 };
  }

  function overlap(a, b) {
    return a.x1 < b.x2 && b.x1 < a.x2 && a.y1 < b.y2 && b.y1 < a.y2;
  }

  function style(large) {
    // Colours by selector, not by a mapper function: a function runs per node on every style pass.
    var byKind = Object.keys(KIND_COLOURS).map(function (kind) {
      return { selector: "node[kind = '" + kind + "']", style: { "background-color": KIND_COLOURS[kind] } };
    });
    // Always-labelled kinds write their label to the right of the node, in the room GAP leaves.
    var labelled = { "label": "data(label)", "min-zoomed-font-size": 7, "text-background-color": "#ffffff",
      "text-background-opacity": 0.8, "text-background-padding": 1, "text-halign": "right", "text-valign": "center",
      "text-margin-x": 4, "text-margin-y": 0, "text-max-width": 140 };
    return [
      // Unlabelled at the starting zoom: placeLabels() names a node once its label can be read and has room.
      { selector: "node", style: {
        "background-color": KIND_COLOURS.other,
        "label": "", "font-size": 11, "color": "#1d2433",
        "text-valign": "bottom", "text-margin-y": 3, "width": 18, "height": 18,
        "text-wrap": "ellipsis", "text-max-width": 130, "text-background-color": "#ffffff",
        "text-background-opacity": 0.8, "text-background-padding": 1 } },
      { selector: "node.named, node.hover, node.focused, node:selected, node.fresh", style: { "label": "data(label)" } }
    ].concat(byKind, [
      { selector: "node[kind = 'robot']", style: Object.assign({ "shape": "round-rectangle", "width": 30, "height": 22,
        "font-weight": "bold", "font-size": 14 }, labelled) },
      { selector: "node[kind = 'human']", style: Object.assign({ "width": 24, "height": 24, "font-weight": "bold",
        "font-size": 14 }, labelled) },
      { selector: "node[kind = 'message']", style: Object.assign({ "shape": "round-rectangle", "font-size": 12 }, labelled) },
      { selector: "node[kind = 'shared-event']", style: { "shape": "diamond" } },
      { selector: "node[kind = 'emotion']", style: { "shape": "star" } },
      { selector: "node[kind = 'model']", style: { "shape": "hexagon" } },
      { selector: "node.hover, node.focused, node:selected", style: { "min-zoomed-font-size": 0, "z-index": 20,
        "text-max-width": 260, "text-background-color": "#ffffff", "text-background-opacity": 0.9 } },
      { selector: "node.folded", style: { "display": "none" } },
      { selector: "node:selected", style: { "border-width": 4, "border-color": "#f4511e" } },
      { selector: "node.fresh", style: { "border-width": 4, "border-color": "#ff8f00", "min-zoomed-font-size": 0 } },
      { selector: "node.focused", style: { "border-width": 4, "border-color": "#12203f", "border-style": "double" } },
      { selector: "node.found", style: { "border-width": 5, "border-color": "#f4511e", "width": 34, "height": 34 } },
      { selector: "edge", style: large ? {
        "curve-style": "haystack", "width": 1, "line-color": "#c3cad6", "opacity": 0.7, "z-index": 1 } : {
        "curve-style": "bezier", "width": 1.2, "line-color": "#b8c0cc", "target-arrow-shape": "triangle",
        "target-arrow-color": "#b8c0cc", "arrow-scale": 0.8, "font-size": 9, "min-zoomed-font-size": 8,
        "color": "#3d4557", "text-rotation": "autorotate", "text-background-color": "#ffffff",
        "text-background-opacity": 0.85, "text-background-padding": 1, "z-index": 1 } },
      // A hub's edges: faint, under the others, no arrow head (in a large drawing, thousands of them would still
      // make a dark fan: not drawn); lit, they come up with it.
      { selector: "edge.hub", style: { "opacity": 0.1, "z-index": 0, "target-arrow-shape": "none" } },
      { selector: "edge.hub", style: large ? { "display": "none" } : {} },
      { selector: "edge.lit", style: Object.assign({ "opacity": 1, "line-color": "#5b6478",
        "target-arrow-color": "#5b6478", "width": 1.6, "z-index": 10 },
        large ? { "display": "element" } : { "target-arrow-shape": "triangle" }) },
      { selector: "edge.labelled", style: { "label": "data(label)" } }, // placed by placeLabels
      { selector: "edge:selected", style: { "line-color": "#f4511e", "width": 2.5 } }
    ]);
  }

  function folded() { return cy.nodes(".folded").length; }

  /* The nodes drawn now: all but the folded ones (a class, so it holds before the next style pass). */
  function shown() { return cy.nodes().not(".folded"); }

  function updateStats() {
    var hidden = folded();
    stats.textContent = cy.nodes().length + " nodes · " + cy.edges().length + " edges" +
      (hidden ? " · " + hidden + " other nodes folded" : "") + viewNote +
      (truncated ? " · truncated: raise the node limit or filter to see the rest" : "");
    stats.dataset.nodes = String(cy.nodes().length);
    stats.dataset.edges = String(cy.edges().length);
    stats.dataset.folded = String(hidden);
    stats.dataset.truncated = String(truncated);
    otherCount.textContent = cy.nodes("[kind = 'other']").length + " other";
    placeLanes();
  }

  /* Lanes: an overlay of bands, one per lane, each holding its lane's nodes and its name at the left, kept in
   * place through pan and zoom. */
  function buildLanes() {
    LANES.forEach(function (kind) {
      var item = el("li", null, "graph-lane lane-" + kind);
      item.appendChild(el("span", LANE_NAMES[kind], "graph-lane-name"));
      item.dataset.kind = kind;
      lanesBox.appendChild(item);
      laneItems[kind] = item;
    });
  }

  /* Each lane's band where its nodes are, and its name on it: just above the lane's first row, else as near
   * as the part of the band in view allows. A name with no room in view is hidden. */
  function placeLanes() {
    var zoom = cy.zoom(), pan = cy.pan(), height = container.clientHeight;
    LANES.forEach(function (kind) {
      var item = laneItems[kind], slot = laneSlots[kind];
      item.hidden = slot === undefined;
      if (item.hidden) { return; }
      var band = laneBand(slot), top = band.top * zoom + pan.y, tall = (band.bottom - band.top) * zoom;
      var name = item.firstChild, nameTall = name.offsetHeight || 14;
      var rows = (slot * laneHeight - laneHalves[kind]) * zoom + pan.y - top; // its first row, from the band's top
      var low = Math.max(0, -top), high = Math.min(tall, height - top) - nameTall;
      item.hidden = high < low;
      item.style.transform = "translateY(" + top + "px)";
      item.style.height = tall + "px";
      name.style.transform = "translateY(" + Math.min(high, Math.max(low, rows - nameTall - 2)) + "px)";
    });
  }

  /* The widest and the tallest name of the lanes drawn now (pixels). */
  function namesSize() {
    var size = { w: 0, h: 0 };
    Object.keys(laneSlots).forEach(function (kind) {
      var item = laneItems[kind], hidden = item.hidden;
      item.hidden = false;
      size.w = Math.max(size.w, item.firstChild.offsetWidth);
      size.h = Math.max(size.h, item.firstChild.offsetHeight);
      item.hidden = hidden;
    });
    return size;
  }

  /* Where the drawing may begin (pixels from the left): past the lanes' names when, at this zoom, there is no
   * room for them between the lanes. */
  function drawingLeft(zoom) {
    var names = namesSize(), tallest = NODE_SIZE / 2;
    Object.keys(laneHalves).forEach(function (kind) { tallest = Math.max(tallest, laneHalves[kind]); });
    var room = (laneHeight - ROWS_SPAN - BAND_MARGIN - (tallest - NODE_SIZE / 2)) * zoom;
    return room >= names.h + 3 ? FIT_PADDING : Math.max(FIT_PADDING, names.w + 16);
  }

  /* The nodes and the labels of robots, humans and messages, right of them (model units). */
  function drawingBox(nodes) {
    var box = nodesBox(nodes), right = box.x2;
    nodes.forEach(function (n) {
      if (LABELLED[n.data("kind")]) { right = Math.max(right, nodeLabelBox(n).x2); }
    });
    return { x1: box.x1, x2: right, y1: box.y1, y2: box.y2, w: right - box.x1, h: box.h };
  }

  /* The zoom that shows the box whole between `left` and the padding (pixels). */
  function zoomToShow(box, left) {
    var width = container.clientWidth - left - FIT_PADDING, height = container.clientHeight - 2 * FIT_PADDING;
    return Math.max(cy.minZoom(), Math.min(cy.maxZoom(), width / Math.max(box.w, 1), height / Math.max(box.h, 1)));
  }

  /* The whole drawing, as large as the box allows (up to `most`), its labels in view and clear of the lanes'
   * names. */
  function showWhole(nodes, most) {
    var box = drawingBox(nodes);
    var zoom = Math.min(most, zoomToShow(box, FIT_PADDING)), left = drawingLeft(zoom);
    zoom = Math.min(zoom, zoomToShow(box, left));
    var width = container.clientWidth - left - FIT_PADDING;
    cy.viewport({ zoom: zoom, pan: { x: left + (width - box.w * zoom) / 2 - box.x1 * zoom,
      y: (container.clientHeight - box.h * zoom) / 2 - box.y1 * zoom } });
  }

  /* Every lane in view, at a zoom where labels can be read if the box is tall enough for that: the whole
   * drawing when it fits at that zoom, else its beginning (left) as far as every lane's first node, all lanes
   * top to bottom. */
  function initialView() {
    var drawn = shown();
    if (drawn.empty()) { return; }
    if (laneHeight !== LANE_HEIGHT || columnScale !== 1) {
      laneHeight = LANE_HEIGHT;
      columnScale = 1;
      arrange();
    }
    viewNote = "";
    var box = drawingBox(drawn), reach = box.x1;
    Object.keys(laneSlots).forEach(function (kind) {
      reach = Math.max(reach, nodesBox(drawn.filter("[kind = '" + kind + "']").min(function (n) {
        return n.position("x");
      }).ele).x2);
    });
    var start = { x1: box.x1, x2: reach + STEP / 2, y1: box.y1, y2: box.y2, w: reach + STEP / 2 - box.x1, h: box.h };
    var zoom = Math.min(READABLE_ZOOM, zoomToShow(start, FIT_PADDING)), left = drawingLeft(zoom);
    zoom = Math.min(zoom, zoomToShow(start, left));
    if (zoomToShow(box, drawingLeft(zoom)) >= zoom) { showWhole(drawn, FIRST_ZOOM); return; }
    cy.viewport({ zoom: zoom, pan: { x: drawingLeft(zoom) - box.x1 * zoom,
      y: (container.clientHeight - box.h * zoom) / 2 - box.y1 * zoom } });
    viewNote = " · showing the start: drag, use the arrow keys or Fit to see the rest";
  }

  function draw(data) {
    truncated = data.truncated;
    large = data.nodes.length > LARGE;
    var positions = layout(data.nodes, data.edges, null);
    cy = cytoscape({
      container: container,
      elements: data.nodes.map(function (n) { return nodeElement(n, positions[n.id]); }).concat(data.edges.map(edgeElement)),
      layout: { name: "preset" },
      style: style(large),
      minZoom: 0.02, maxZoom: 4,
      textureOnViewport: large, hideEdgesOnViewport: large, pixelRatio: large ? 1 : "auto",
      renderer: { name: "canvas", webgl: large && WEBGL },
      boxSelectionEnabled: false
    });
    arrange();
    markHubEdges(cy.edges());
    cy.on("tap", "node", function (event) { setFocus(event.target, false); openPanel(event.target.id(), false); });
    cy.on("mouseover", "node", function (event) { event.target.addClass("hover"); lightEdges(); });
    cy.on("mouseout", "node", function (event) { event.target.removeClass("hover"); lightEdges(); });
    cy.on("select unselect", "node", lightEdges);
    cy.on("viewport", function () {
      placeLanes();
      if (labelsAt !== labelLevel()) { placeLabels(); }
    });
    initialView();
    cy.one("render", function () {
      var elapsed = Math.round(performance.now() - started);
      window.segbGraph = {
        ready: true, nodes: cy.nodes().length, edges: cy.edges().length, ms: elapsed,
        fetchMs: Math.round(fetchedAt - started), drawMs: Math.round(performance.now() - fetchedAt),
        labelsShown: labelsShown,
        has: function (id) { return cy.getElementById(id).nonempty(); },
        isFresh: function (id) { return cy.getElementById(id).hasClass("fresh"); }
      };
      container.dataset.ready = "true";
      container.dataset.renderMs = String(elapsed);
      updateStats();
      if (data.matches && data.matches.length) { focusNode(data.matches[0], false); }
    });
    if (!data.nodes.length) {
      stats.textContent = "No nodes match — robots have not published yet, or the filters exclude everything.";
    }
  }

  /* The nodes in view whose label is drawn at the current zoom, as "kind: label" (for checks and tests). */
  function labelsShown() {
    var zoom = cy.zoom(), width = container.clientWidth, height = container.clientHeight;
    return shown().filter(function (n) {
      var at = n.renderedPosition();
      var drawn = n.pstyle("label").strValue !== "" &&
        n.pstyle("font-size").pfValue * zoom >= n.pstyle("min-zoomed-font-size").pfValue;
      return drawn && at.x >= 0 && at.y >= 0 && at.x <= width && at.y <= height;
    }).map(function (n) { return n.data("kind") + ": " + n.data("label"); });
  }

  /* Select a node, bring it into view and open its details; `moveFocus` sends keyboard focus to them. */
  function focusNode(id, moveFocus) {
    var node = cy.getElementById(id);
    if (!node || node.empty()) { return false; }
    if (node.hasClass("folded")) {
      node.removeClass("folded"); // a node asked for by name is shown even while its kind is folded
      arrange();
    }
    cy.nodes(".found").removeClass("found");
    cy.$(":selected").unselect();
    node.addClass("found").select();
    setFocus(node, false);
    cy.animate({ center: { eles: node }, zoom: Math.max(cy.zoom(), 1.2) }, { duration: 250 });
    openPanel(id, moveFocus);
    return true;
  }

  function search(query) {
    var needle = query.trim().toLowerCase();
    if (!needle) { return; }
    var hit = cy.nodes().filter(function (n) {
      return String(n.data("label")).toLowerCase().indexOf(needle) >= 0 || n.id().toLowerCase().indexOf(needle) >= 0;
    });
    if (hit.nonempty()) { focusNode(hit[0].id(), false); return; }
    // Not drawn yet: ask the server, merge what it finds, then focus.
    fetchJson("/kg-graph/data?" + new URLSearchParams({ q: query.trim(), limit: "200" })).then(function (data) {
      merge(data, null);
      if (!data.matches.length || !focusNode(data.matches[0], false)) {
        stats.textContent = "Nothing named “" + query.trim() + "” in the graph.";
      }
    }).catch(showError);
  }

  function merge(data, around) {
    var fresh = data.nodes.filter(function (n) { return cy.getElementById(n.id).empty(); });
    var anchor = around ? { x: around.data("x0") } : null; // in time's columns before any spread
    var positions = layout(fresh, data.edges.filter(function (e) {
      return fresh.some(function (n) { return n.id === e.source || n.id === e.target; });
    }), anchor);
    cy.add(fresh.map(function (n) { return nodeElement(n, positions[n.id]); }));
    markHubEdges(cy.add(data.edges.filter(function (e) { return cy.getElementById(e.id).empty(); }).map(edgeElement)));
    arrange();
    updateStats();
    refreshList();
    return fresh;
  }

  function expand(id) {
    var node = cy.getElementById(id);
    fetchJson("/kg-graph/data?" + new URLSearchParams({ focus: id, depth: "1", limit: "400" })).then(function (data) {
      var added = merge(data, node);
      stats.textContent += " · expanded: " + added.length + " new nodes";
    }).catch(showError);
  }

  /* --- keyboard: the drawing as one focusable widget ------------------------------------------------ */

  function describe(node) {
    var time = node.data("time");
    return node.data("label") + " (" + node.data("kind") + (time ? ", " + time : "") + ")";
  }

  function setFocus(node, bringIntoView) {
    if (focused && !focused.removed()) { focused.removeClass("focused"); }
    focused = node.addClass("focused");
    lightEdges();
    if (bringIntoView) {
      var at = node.renderedPosition();
      if (at.x < 40 || at.y < 40 || at.x > container.clientWidth - 40 || at.y > container.clientHeight - 40) {
        cy.animate({ center: { eles: node } }, { duration: 150 });
      }
      announce.textContent = describe(node) + ". Enter opens its details.";
    }
  }

  function startingNode() {
    var visible = shown();
    var robots = visible.filter("[kind = 'robot']");
    return robots.nonempty() ? robots[0] : visible[0];
  }

  /* The nearest visible node in one direction, preferring nodes in line with the current one. */
  function step(direction) {
    if (!focused || focused.removed() || focused.hasClass("folded")) {
      var first = startingNode();
      if (first) { setFocus(first, true); }
      return;
    }
    var from = focused.position(), best = null, bestScore = Infinity;
    shown().forEach(function (n) {
      if (n.same(focused)) { return; }
      var p = n.position(), dx = p.x - from.x, dy = p.y - from.y;
      var along = direction[0] ? dx * direction[0] : dy * direction[1];
      var across = direction[0] ? Math.abs(dy) : Math.abs(dx);
      if (along <= 0) { return; }
      var score = along + 2 * across;
      if (score < bestScore) { bestScore = score; best = n; }
    });
    if (best) { setFocus(best, true); } else { announce.textContent = "No node further that way."; }
  }

  function zoomBy(factor) {
    var at = focused && !focused.hasClass("folded") ? focused.renderedPosition()
      : { x: container.clientWidth / 2, y: container.clientHeight / 2 };
    cy.zoom({ level: cy.zoom() * factor, renderedPosition: at });
    announce.textContent = "Zoom " + Math.round(cy.zoom() * 100) + " %";
  }

  /* Where the nodes are, their labels left out: most are not drawn at the zoom that shows everything. */
  function nodesBox(nodes) {
    return nodes.boundingBox({ includeLabels: false, includeOverlays: false, includeUnderlays: false });
  }

  /* The whole drawing, filling the box: a drawing wider than the box leaves the box's height empty at the
   * zoom that fits its width, so the lanes are first moved apart (up to MAX_LANE_STRETCH) to fill it; one
   * taller than the box leaves its width empty, so the time columns are moved apart (up to
   * MAX_COLUMN_STRETCH). */
  function fitAll() {
    var drawn = shown();
    if (drawn.empty()) { return; }
    laneHeight = LANE_HEIGHT;
    columnScale = 1;
    arrange();
    var box = nodesBox(drawn), lanes = Object.keys(laneSlots).length;
    var width = container.clientWidth - 2 * FIT_PADDING, height = container.clientHeight - 2 * FIT_PADDING;
    var timed = box.x2 - Math.max(box.x1, 0); // the part that spreads with the columns
    if (lanes > 1 && box.w / box.h > width / height) {
      var wanted = (box.w * height / width - (box.h - (lanes - 1) * laneHeight)) / (lanes - 1);
      laneHeight = Math.min(LANE_HEIGHT * MAX_LANE_STRETCH, Math.max(LANE_HEIGHT, wanted));
    } else if (timed > 0) {
      columnScale = Math.min(MAX_COLUMN_STRETCH, Math.max(1, (box.h * width / height - (box.w - timed)) / timed));
    }
    arrange();
    showWhole(drawn, cy.maxZoom());
    placeLanes();
    announce.textContent = "The whole drawing, zoom " + Math.round(cy.zoom() * 100) + " %";
  }

  container.addEventListener("keydown", function (event) {
    if (!cy || event.altKey || event.ctrlKey || event.metaKey) { return; }
    var key = event.key;
    if (ARROWS[key]) {
      event.preventDefault();
      step(ARROWS[key]);
    } else if ((key === "Enter" || key === " ") && focused) {
      event.preventDefault();
      cy.$(":selected").unselect();
      focused.select();
      openPanel(focused.id(), false);
      announce.textContent = "Details of " + describe(focused) + " are beside the drawing.";
    } else if (key === "+" || key === "=") {
      event.preventDefault();
      zoomBy(1.25);
    } else if (key === "-" || key === "_") {
      event.preventDefault();
      zoomBy(0.8);
    } else if (key === "0") {
      event.preventDefault();
      fitAll();
    }
  });
  container.addEventListener("focus", function () {
    if (cy && !focused) {
      var first = startingNode();
      if (first) { setFocus(first, true); }
    }
  });

  /* --- the drawn nodes as a list (for keyboards and screen readers) -------------------------------- */

  function refreshList() {
    if (!list.open || !cy) { return; }
    var parts = [];
    LANES.forEach(function (kind) {
      var nodes = shown().filter("[kind = '" + kind + "']");
      if (nodes.empty()) { return; }
      parts.push(el("h3", LANE_NAMES[kind] + " (" + nodes.length + ")"));
      var items = el("ul", null, "graph-list-items");
      nodes.forEach(function (n) {
        var button = el("button", n.data("label"), "link-button");
        button.type = "button";
        button.dataset.id = n.id();
        if (n.data("time")) { button.appendChild(el("span", " · " + n.data("time"), "muted")); }
        var item = el("li");
        item.appendChild(button);
        items.appendChild(item);
      });
      parts.push(items);
    });
    if (!parts.length) { parts.push(el("p", "Nothing is drawn.", "muted")); }
    listBody.replaceChildren.apply(listBody, parts);
  }

  list.addEventListener("toggle", refreshList);
  listBody.addEventListener("click", function (event) {
    var button = event.target.closest("button[data-id]");
    if (button && cy) { focusNode(button.dataset.id, true); }
  });

  /* --- the details panel --------------------------------------------------------------------------- */

  function statementTable(title, statements) {
    var section = el("section");
    section.appendChild(el("h3", title + " (" + statements.length + ")"));
    // Two values of one predicate with the same label (rdf:type Person from FOAF and from PROV) are told
    // apart by their vocabulary.
    var seen = {};
    statements.forEach(function (s) {
      if (!s.is_literal) {
        var key = s.predicate + "\n" + named(s.value, s.label);
        seen[key] = (seen[key] || 0) + 1;
      }
    });
    var table = el("table");
    statements.forEach(function (s) {
      var row = el("tr");
      row.appendChild(el("td", s.predicate_label, "muted"));
      var cell = el("td");
      if (s.is_literal) {
        cell.textContent = String(s.value) + (s.language ? " @" + s.language : "");
      } else {
        var link = el("a", named(s.value, s.label));
        link.href = "#";
        link.title = String(s.value);
        link.addEventListener("click", function (event) {
          event.preventDefault();
          if (!focusNode(String(s.value), true)) { openPanel(String(s.value), true); }
        });
        cell.appendChild(link);
        if (seen[s.predicate + "\n" + named(s.value, s.label)] > 1 && compact(s.value) !== String(s.value)) {
          cell.appendChild(el("span", " " + compact(s.value), "muted vocabulary"));
        }
      }
      row.appendChild(cell);
      table.appendChild(row);
    });
    section.appendChild(table);
    return section;
  }

  /* A resource as the drawing labels it (which Maria; whose state, when), else by its name. */
  function named(iri, label) {
    var drawn = cy ? cy.getElementById(iri) : null;
    return drawn && drawn.nonempty() ? drawn.data("label") : readable(iri, label);
  }

  /* A node's heading: its name; a shared event, which has none, by what it is about, when and its words. */
  function title(resource) {
    if (resource.kind !== "shared-event") { return named(resource.iri, resource.label); }
    var about = resource.outgoing.filter(function (s) { return /[\/#]about$/.test(s.predicate) && !s.is_literal; })
      .map(function (s) { return named(s.value, s.label); });
    var words = resource.outgoing.filter(function (s) { return s.is_literal && /[\/#]description$/.test(s.predicate); });
    return "Shared event" + (about.length ? " about " + about.join(", ") : "") +
      (resource.time ? " at " + resource.time.replace(/^.*T/, "").replace(/Z$/, "") : "") +
      (words.length ? " — “" + words[0].value + "”" : "");
  }

  function openPanel(id, moveFocus) {
    panel.replaceChildren(el("p", "Loading…", "muted"));
    fetchJson("/kg-graph/resource?" + new URLSearchParams({ iri: id })).then(function (resource) {
      var parts = [];
      var heading = el("h2", title(resource));
      heading.tabIndex = -1;
      heading.title = resource.iri;
      parts.push(heading);
      var kind = el("p");
      kind.appendChild(el("span", null, "swatch kind-" + resource.kind));
      kind.appendChild(document.createTextNode(resource.kind + (resource.time ? " · " + resource.time : "")));
      parts.push(kind);
      if (resource.types.length) { parts.push(el("p", "Types: " + resource.types.join(", "))); }
      var actions = el("div", null, "actions");
      // The IRI is an id: on hover and to copy, not in the text.
      var copy = el("button", "Copy IRI", "secondary panel-iri");
      copy.type = "button";
      copy.title = resource.iri;
      copy.addEventListener("click", function () {
        if (!navigator.clipboard) { return; }
        navigator.clipboard.writeText(resource.iri).then(function () { copy.textContent = "IRI copied"; }, function () {});
      });
      var explain = el("a", "Explain", "button");
      explain.href = "/explain?" + new URLSearchParams({ iri: resource.iri });
      var grow = el("button", "Expand neighbours", "secondary");
      grow.type = "button";
      grow.addEventListener("click", function () {
        if (cy.getElementById(resource.iri).empty()) {
          fetchJson("/kg-graph/data?" + new URLSearchParams({ focus: resource.iri, depth: "1", limit: "400" }))
            .then(function (data) { merge(data, null); focusNode(resource.iri, false); }).catch(showError);
        } else { expand(resource.iri); }
      });
      actions.appendChild(explain);
      actions.appendChild(grow);
      actions.appendChild(copy);
      parts.push(actions);
      parts.push(statementTable("Outgoing", resource.outgoing));
      parts.push(statementTable("Incoming", resource.incoming));
      if (resource.incoming_truncated) {
        parts.push(el("p", "Only the first " + resource.incoming.length + " incoming statements are listed; " +
          "more point at this resource. Expand its neighbours or query it in SPARQL to see them all.",
          "muted incoming-truncated"));
      }
      panel.replaceChildren.apply(panel, parts);
      panel.dataset.iri = resource.iri;
      if (moveFocus) { heading.focus(); }
    }).catch(function (error) { panel.replaceChildren(el("p", error.message, "banner banner-error")); });
  }

  /* --- toolbar ------------------------------------------------------------------------------------- */

  document.getElementById("graph-search").addEventListener("submit", function (event) {
    event.preventDefault();
    if (cy) { search(document.getElementById("graph-search-input").value); }
  });
  document.getElementById("graph-fit").addEventListener("click", function () { if (cy) { fitAll(); } });
  showOther.addEventListener("change", function () {
    if (!cy) { return; }
    var others = cy.nodes("[kind = 'other']");
    if (showOther.checked) { others.removeClass("folded"); } else { others.not(":selected").addClass("folded"); }
    arrange();
    updateStats();
    refreshList();
  });

  /* --- live: what robots publish joins the drawing ----------------------------------------------------
   * One Server-Sent Events stream (relayed by this UI with the viewer's session) says the graph changed; the
   * page's own view is fetched again and what is new merged in, marked for a moment. Nodes already drawn keep
   * their place; the node panel and the focus stay. A button pauses and resumes (resuming fetches once if
   * anything changed meanwhile). */

  var liveToggle = document.getElementById("graph-live");
  var liveSource = null, liveTimer = null, liveId = "";

  function refreshLive() {
    liveTimer = null;
    if (!cy) { return; }
    fetchJson(container.dataset.src).then(function (data) {
      var added = merge(data, null);
      if (!added.length) { return; }
      var nodes = cy.collection(added.map(function (n) { return cy.getElementById(n.id); }));
      nodes.addClass("fresh");
      window.setTimeout(function () { nodes.removeClass("fresh"); }, 4000);
      announce.textContent = added.length + " new " + (added.length === 1 ? "node" : "nodes") + " published";
    }).catch(showError);
  }

  function startLive() {
    liveSource = new EventSource("/live/graph" + (liveId ? "?after=" + encodeURIComponent(liveId) : ""));
    liveSource.addEventListener("change", function (event) {
      liveId = event.lastEventId || liveId;
      if (!liveTimer) { liveTimer = window.setTimeout(refreshLive, 300); }  // a burst of posts: one fetch
    });
    liveToggle.setAttribute("aria-pressed", "true");
    liveToggle.textContent = "Live updates: on";
  }

  function stopLive() {
    if (liveSource) { liveSource.close(); }
    liveSource = null;
    liveToggle.setAttribute("aria-pressed", "false");
    liveToggle.textContent = "Live updates: paused";
  }

  buildLanes();
  fetchJson(container.dataset.src).then(function (data) {
    fetchedAt = performance.now();
    draw(data);
    liveId = data.through === undefined ? "" : String(data.through);  // changes after the drawing's own
    if (liveToggle && window.EventSource) {
      liveToggle.hidden = false;
      liveToggle.addEventListener("click", function () { if (liveSource) { stopLive(); } else { startLive(); } });
      startLive();
    }
  }).catch(showError);
})();
