// Keeps the report sections of a page current while robots publish: one Server-Sent Events stream (relayed by
// this UI with the viewer's session) says which reports changed; the page is fetched again with its own
// filters and the changed sections swapped in, their new rows marked for a moment. One fetch serves every report
// changed meanwhile, and one at a time is on its way: a burst of posts costs a fetch or two, not one per report
// and post. A button pauses and resumes; resuming replays the changes missed meanwhile.
(function () {
  "use strict";
  var sections = document.querySelectorAll("section[data-report]");
  var toggle = document.getElementById("live-toggle");
  if (!sections.length || !toggle || !window.EventSource || !window.segbLiveToggle) return;
  var changed = {};  // reports changed since the last fetch began
  var fetching = false;
  var gathering = null;
  // The stream starts where the page's rows end (a change made while the page loaded is announced), and
  // resuming after a pause asks for what came since (a new EventSource forgets it).
  var lastId = toggle.dataset.after || "";
  // The events of one group of changes arrive together: a moment's wait gathers them into one fetch.
  var GATHER_MS = 30;

  function rowsOf(section) {
    var seen = {};
    section.querySelectorAll("tbody tr, .thread li, .message").forEach(function (row) {
      seen[row.textContent.trim()] = true;
    });
    return seen;
  }

  function swap(doc, name) {
    var current = document.getElementById("report-" + name);
    var fresh = doc.getElementById("report-" + name);
    if (!current || !fresh) return;
    var before = rowsOf(current);
    current.replaceWith(fresh);
    fresh.querySelectorAll("tbody tr, .thread li, .message").forEach(function (row) {
      if (!before[row.textContent.trim()]) {
        row.classList.add("fresh");
        window.setTimeout(function () { row.classList.remove("fresh"); }, 4000);
      }
    });
  }

  function refresh() {
    gathering = null;
    var names = Object.keys(changed);
    if (fetching || !names.length) return;
    changed = {};
    fetching = true;
    fetch(window.location.href, { credentials: "same-origin", headers: { Accept: "text/html" } })
      .then(function (answer) { return answer.ok ? answer.text() : null; })
      .then(function (html) {
        if (!html) return;
        var doc = new DOMParser().parseFromString(html, "text/html");
        names.forEach(function (name) { swap(doc, name); });
      })
      .catch(function () {})  // a page that cannot be fetched now is fetched at the next change
      .then(function () {
        fetching = false;
        if (Object.keys(changed).length) later();  // what changed while this fetch was on its way
      });
  }

  function later() {
    if (gathering === null) gathering = window.setTimeout(refresh, GATHER_MS);
  }

  window.segbLiveToggle(toggle, function () {
    var names = Array.prototype.map.call(sections, function (section) { return section.dataset.report; });
    var query = names.map(function (name) { return "report=" + encodeURIComponent(name); }).join("&");
    var source = new EventSource("/live/reports?" + query + (lastId ? "&after=" + encodeURIComponent(lastId) : ""));
    source.addEventListener("change", function (event) {
      lastId = event.lastEventId || lastId;
      changed[JSON.parse(event.data).report] = true;
      later();
    });
    source.addEventListener("reset", function () {
      names.forEach(function (name) { changed[name] = true; });
      later();
    });
    return source;
  });
})();
