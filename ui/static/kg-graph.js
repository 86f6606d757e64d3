/* Knowledge-graph explorer: draws /kg-graph/data with cytoscape.js (vendored), opens node details from
 * /kg-graph/resource, merges neighbourhoods on demand. Every text from the graph is set with textContent:
 * robot-supplied strings never become markup. */
(function () {
  "use strict";

  var KIND_COLOURS = {
    robot: "#12203f", human: "#e6a700", "shared-event": "#7b3fb5", activity: "#2f5fd0", message: "#00838f",
    emotion: "#c62828", state: "#2e7d32", model: "#8d6e63", other: "#9aa3b5"
  };
  // Lanes from top to bottom; within a lane, time runs left to right.
  var LANES = ["robot", "human", "shared-event", "activity", "message", "emotion", "state", "model", "other"];
  var LANE_HEIGHT = 170, SUB_ROW = 34, SUB_ROWS = 4, STEP = 42;
  var LARGE = 400; // above this many nodes, drawing favours speed over detail (straight edges, no edge labels)

  var container = document.getElementById("graph");
  // WebGL drawing (cytoscape 3.31+) is opt-in: software GL in headless or GPU-less browsers is slower than canvas.
  var WEBGL = new URLSearchParams(window.location.search).get("renderer") === "webgl";
  var panel = document.getElementById("graph-panel");
  var stats = document.getElementById("graph-stats");
  var errorBox = document.getElementById("graph-error");
  var started = performance.now();
  var cy = null;
  var truncated = false;

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

  /* Positions: timed nodes by time rank; untimed nodes at the mean of their placed neighbours; then each
   * lane spreads its nodes over a few sub-rows so they do not overlap. Linear in nodes and edges. */
  function layout(nodes, edges, anchor) {
    var x = {}, adjacency = {};
    edges.forEach(function (e) {
      (adjacency[e.source] = adjacency[e.source] || []).push(e.target);
      (adjacency[e.target] = adjacency[e.target] || []).push(e.source);
    });
    var timed = nodes.filter(function (n) { return n.time; });
    timed.sort(function (a, b) { return a.time < b.time ? -1 : a.time > b.time ? 1 : 0; });
    var offset = anchor ? anchor.x : 0;
    timed.forEach(function (n, i) { x[n.id] = offset + i * STEP; });
    for (var pass = 0; pass < 2; pass++) {
      nodes.forEach(function (n) {
        if (n.time) { return; }
        var xs = (adjacency[n.id] || []).map(function (m) { return x[m]; }).filter(function (v) { return v !== undefined; });
        if (xs.length) { x[n.id] = xs.reduce(function (a, b) { return a + b; }, 0) / xs.length; }
      });
    }
    nodes.forEach(function (n, i) { if (x[n.id] === undefined) { x[n.id] = offset + i * STEP; } });
    var byLane = {};
    nodes.forEach(function (n) { (byLane[n.kind] = byLane[n.kind] || []).push(n); });
    var positions = {};
    Object.keys(byLane).forEach(function (kind) {
      var lane = Math.max(0, LANES.indexOf(kind));
      var lastX = [];
      for (var r = 0; r < SUB_ROWS; r++) { lastX.push(-Infinity); }
      byLane[kind].sort(function (a, b) { return x[a.id] - x[b.id]; });
      byLane[kind].forEach(function (n) {
        var want = x[n.id], row = 0, best = 0;
        for (row = 0; row < SUB_ROWS; row++) {
          if (want - lastX[row] >= STEP) { break; }
          if (lastX[row] < lastX[best]) { best = row; }
        }
        if (row === SUB_ROWS) { row = best; want = lastX[best] + STEP; }
        lastX[row] = want;
        positions[n.id] = { x: want, y: lane * LANE_HEIGHT + row * SUB_ROW };
      });
    });
    return positions;
  }

  function elementsOf(data, positions) {
    var nodes = data.nodes.map(function (n) {
      return { group: "nodes", data: { id: n.id, label: n.label, kind: n.kind, time: n.time || "" }, position: positions[n.id] };
    });
    var edges = data.edges.map(function (e) {
      return { group: "edges", data: { id: e.id, source: e.source, target: e.target, label: e.label } };
    });
    return nodes.concat(edges);
  }

  function style(large) {
    // Colours by selector, not by a mapper function: a function runs per node on every style pass.
    var byKind = Object.keys(KIND_COLOURS).map(function (kind) {
      return { selector: "node[kind = '" + kind + "']", style: { "background-color": KIND_COLOURS[kind] } };
    });
    return [
      { selector: "node", style: {
        "background-color": KIND_COLOURS.other,
        "label": "data(label)", "font-size": 11, "min-zoomed-font-size": 9, "color": "#1d2433",
        "text-valign": "bottom", "text-margin-y": 3, "width": 18, "height": 18 } }
    ].concat(byKind, [
      { selector: "node[kind = 'robot']", style: { "shape": "round-rectangle", "width": 34, "height": 26, "font-weight": "bold" } },
      { selector: "node[kind = 'human']", style: { "width": 30, "height": 30, "font-weight": "bold" } },
      { selector: "node[kind = 'shared-event']", style: { "shape": "diamond" } },
      { selector: "node[kind = 'message']", style: { "shape": "round-rectangle" } },
      { selector: "node[kind = 'emotion']", style: { "shape": "star" } },
      { selector: "node[kind = 'model']", style: { "shape": "hexagon" } },
      { selector: "node:selected", style: { "border-width": 4, "border-color": "#f4511e" } },
      { selector: "node.found", style: { "border-width": 5, "border-color": "#f4511e", "width": 34, "height": 34 } },
      { selector: "edge", style: large ? {
        "curve-style": "haystack", "width": 1, "line-color": "#c3cad6", "opacity": 0.7 } : {
        "curve-style": "bezier", "width": 1.2, "line-color": "#b8c0cc", "target-arrow-shape": "triangle",
        "target-arrow-color": "#b8c0cc", "arrow-scale": 0.8, "label": "data(label)", "font-size": 8,
        "min-zoomed-font-size": 10, "color": "#5b6478", "text-rotation": "autorotate" } },
      { selector: "edge:selected", style: { "line-color": "#f4511e", "width": 2.5 } }
    ]);
  }

  function updateStats() {
    stats.textContent = cy.nodes().length + " nodes · " + cy.edges().length + " edges" +
      (truncated ? " · truncated: raise the node limit or filter to see the rest" : "");
    stats.dataset.nodes = String(cy.nodes().length);
    stats.dataset.edges = String(cy.edges().length);
    stats.dataset.truncated = String(truncated);
  }

  function draw(data) {
    truncated = data.truncated;
    var large = data.nodes.length > LARGE;
    var positions = layout(data.nodes, data.edges, null);
    cy = cytoscape({
      container: container,
      elements: elementsOf(data, positions),
      layout: { name: "preset" },
      style: style(large),
      minZoom: 0.02, maxZoom: 4,
      textureOnViewport: large, hideEdgesOnViewport: large, pixelRatio: large ? 1 : "auto",
      renderer: { name: "canvas", webgl: large && WEBGL },
      boxSelectionEnabled: false
    });
    cy.on("tap", "node", function (event) { openPanel(event.target.id()); });
    cy.one("render", function () {
      var elapsed = Math.round(performance.now() - started);
      window.segbGraph = {
        ready: true, nodes: cy.nodes().length, edges: cy.edges().length, ms: elapsed,
        fetchMs: Math.round(fetchedAt - started), drawMs: Math.round(performance.now() - fetchedAt)
      };
      container.dataset.ready = "true";
      container.dataset.renderMs = String(elapsed);
      updateStats();
      if (data.matches && data.matches.length) { focusNode(data.matches[0]); }
    });
    if (!data.nodes.length) {
      stats.textContent = "No nodes match — robots have not published yet, or the filters exclude everything.";
    }
  }

  function focusNode(id) {
    var node = cy.getElementById(id);
    if (!node || node.empty()) { return false; }
    cy.nodes(".found").removeClass("found");
    cy.$(":selected").unselect();
    node.addClass("found").select();
    cy.animate({ center: { eles: node }, zoom: Math.max(cy.zoom(), 1.2) }, { duration: 250 });
    openPanel(id);
    return true;
  }

  function search(query) {
    var needle = query.trim().toLowerCase();
    if (!needle) { return; }
    var hit = cy.nodes().filter(function (n) {
      return String(n.data("label")).toLowerCase().indexOf(needle) >= 0 || n.id().toLowerCase().indexOf(needle) >= 0;
    });
    if (hit.nonempty()) { focusNode(hit[0].id()); return; }
    // Not drawn yet: ask the server, merge what it finds, then focus.
    fetchJson("/kg-graph/data?" + new URLSearchParams({ q: query.trim(), limit: "200" })).then(function (data) {
      merge(data, null);
      if (!data.matches.length || !focusNode(data.matches[0])) {
        stats.textContent = "Nothing named “" + query.trim() + "” in the graph.";
      }
    }).catch(showError);
  }

  function merge(data, around) {
    var fresh = { nodes: data.nodes.filter(function (n) { return cy.getElementById(n.id).empty(); }), edges: [] };
    var anchor = around ? around.position() : null;
    var positions = layout(fresh.nodes, data.edges.filter(function (e) {
      return fresh.nodes.some(function (n) { return n.id === e.source || n.id === e.target; });
    }), anchor);
    cy.add(elementsOf(fresh, positions));
    cy.add(data.edges.filter(function (e) { return cy.getElementById(e.id).empty(); }).map(function (e) {
      return { group: "edges", data: { id: e.id, source: e.source, target: e.target, label: e.label } };
    }));
    updateStats();
    return fresh.nodes.length;
  }

  function expand(id) {
    var node = cy.getElementById(id);
    fetchJson("/kg-graph/data?" + new URLSearchParams({ focus: id, depth: "1", limit: "400" })).then(function (data) {
      var added = merge(data, node);
      stats.textContent += " · expanded: " + added + " new nodes";
    }).catch(showError);
  }

  function statementTable(title, statements, incoming) {
    var section = el("section");
    section.appendChild(el("h3", title + " (" + statements.length + ")"));
    var table = el("table");
    statements.forEach(function (s) {
      var row = el("tr");
      row.appendChild(el("td", s.predicate_label, "muted"));
      var cell = el("td");
      if (s.is_literal) {
        cell.textContent = String(s.value) + (s.language ? " @" + s.language : "");
      } else {
        var link = el("a", s.label || s.value);
        link.href = "#";
        link.title = String(s.value);
        link.addEventListener("click", function (event) {
          event.preventDefault();
          if (!focusNode(String(s.value))) { openPanel(String(s.value)); }
        });
        cell.appendChild(link);
      }
      row.appendChild(cell);
      table.appendChild(row);
    });
    section.appendChild(table);
    return section;
  }

  function openPanel(id) {
    panel.replaceChildren(el("p", "Loading…", "muted"));
    fetchJson("/kg-graph/resource?" + new URLSearchParams({ iri: id })).then(function (resource) {
      var parts = [];
      parts.push(el("h2", resource.label));
      var kind = el("p");
      var swatch = el("span", null, "swatch kind-" + resource.kind);
      kind.appendChild(swatch);
      kind.appendChild(document.createTextNode(resource.kind + (resource.time ? " · " + resource.time : "")));
      parts.push(kind);
      parts.push(el("p", resource.iri, "muted panel-iri"));
      if (resource.types.length) { parts.push(el("p", "Types: " + resource.types.join(", "))); }
      var actions = el("div", null, "actions");
      var explain = el("a", "Explain", "button");
      explain.href = "/explain?" + new URLSearchParams({ iri: resource.iri });
      var grow = el("button", "Expand neighbours", "secondary");
      grow.type = "button";
      grow.addEventListener("click", function () {
        if (cy.getElementById(resource.iri).empty()) {
          fetchJson("/kg-graph/data?" + new URLSearchParams({ focus: resource.iri, depth: "1", limit: "400" }))
            .then(function (data) { merge(data, null); focusNode(resource.iri); }).catch(showError);
        } else { expand(resource.iri); }
      });
      actions.appendChild(explain);
      actions.appendChild(grow);
      parts.push(actions);
      parts.push(statementTable("Outgoing", resource.outgoing, false));
      parts.push(statementTable("Incoming", resource.incoming, true));
      panel.replaceChildren.apply(panel, parts);
      panel.dataset.iri = resource.iri;
    }).catch(function (error) { panel.replaceChildren(el("p", error.message, "banner banner-error")); });
  }

  document.getElementById("graph-search").addEventListener("submit", function (event) {
    event.preventDefault();
    if (cy) { search(document.getElementById("graph-search-input").value); }
  });
  document.getElementById("graph-fit").addEventListener("click", function () { if (cy) { cy.fit(undefined, 30); } });

  var fetchedAt = 0;
  fetchJson(container.dataset.src).then(function (data) { fetchedAt = performance.now(); draw(data); }).catch(showError);
})();
