// Keeps the report sections of a page current while robots publish: one Server-Sent Events stream (relayed by
// this UI with the viewer's session) says which reports changed; each changed section is fetched again with the
// page's own filters and swapped in, its new rows marked for a moment. A button pauses and resumes; resuming
// replays the changes missed meanwhile.
(function () {
  "use strict";
  var sections = document.querySelectorAll("section[data-report]");
  var toggle = document.getElementById("live-toggle");
  if (!sections.length || !toggle || !window.EventSource) return;
  var source = null;
  var pending = {};
  // The stream starts where the page's rows end (a change made while the page loaded is announced), and
  // resuming after a pause asks for what came since (a new EventSource forgets it).
  var lastId = toggle.dataset.after || "";

  function rowsOf(section) {
    var seen = {};
    section.querySelectorAll("tbody tr, .thread li, .message").forEach(function (row) {
      seen[row.textContent.trim()] = true;
    });
    return seen;
  }

  function refresh(name) {
    pending[name] = null;
    var current = document.getElementById("report-" + name);
    if (!current) return;
    fetch(window.location.href, { credentials: "same-origin", headers: { Accept: "text/html" } })
      .then(function (answer) { return answer.ok ? answer.text() : null; })
      .then(function (html) {
        if (!html) return;
        var fresh = new DOMParser().parseFromString(html, "text/html").getElementById("report-" + name);
        if (!fresh) return;
        var before = rowsOf(current);
        current.replaceWith(fresh);
        fresh.querySelectorAll("tbody tr, .thread li, .message").forEach(function (row) {
          if (!before[row.textContent.trim()]) {
            row.classList.add("fresh");
            window.setTimeout(function () { row.classList.remove("fresh"); }, 4000);
          }
        });
      });
  }

  function start() {
    var names = Array.prototype.map.call(sections, function (section) { return section.dataset.report; });
    var query = names.map(function (name) { return "report=" + encodeURIComponent(name); }).join("&");
    source = new EventSource("/live/reports?" + query + (lastId ? "&after=" + encodeURIComponent(lastId) : ""));
    source.addEventListener("change", function (event) {
      lastId = event.lastEventId || lastId;
      var name = JSON.parse(event.data).report;
      if (pending[name]) return;  // a refresh is already on its way
      pending[name] = window.setTimeout(function () { refresh(name); }, 250);
    });
    source.addEventListener("reset", function () { names.forEach(refresh); });
    toggle.setAttribute("aria-pressed", "true");
    toggle.textContent = "Live updates: on";
  }

  function stop() {
    if (source) source.close();
    source = null;
    toggle.setAttribute("aria-pressed", "false");
    toggle.textContent = "Live updates: paused";
  }

  toggle.hidden = false;
  toggle.addEventListener("click", function () { if (source) stop(); else start(); });
  start();
})();
