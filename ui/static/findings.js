// Keeps the findings page current while robots publish: the findings' Server-Sent Events stream (relayed by this
// UI with the viewer's session) says that findings appeared or went; the page is fetched again with its own
// filters and its counts and list swapped in, new findings marked for a moment. One fetch at a time is on its
// way. A button pauses and resumes.
(function () {
  "use strict";
  var region = document.getElementById("findings-live");
  var toggle = document.getElementById("live-toggle");
  if (!region || !toggle || !window.EventSource) return;
  var source = null;
  var fetching = false;
  var again = false;
  var lastId = toggle.dataset.after || "";

  function keys(root) {
    var seen = {};
    root.querySelectorAll("tr.finding").forEach(function (row) { seen[row.textContent.trim()] = true; });
    return seen;
  }

  function refresh() {
    if (fetching) { again = true; return; }
    fetching = true;
    fetch(window.location.href, { credentials: "same-origin", headers: { Accept: "text/html" } })
      .then(function (answer) { return answer.ok ? answer.text() : null; })
      .then(function (html) {
        if (!html) return;
        var fresh = new DOMParser().parseFromString(html, "text/html").getElementById("findings-live");
        var current = document.getElementById("findings-live");
        if (!fresh || !current) return;
        var before = keys(current);
        current.replaceWith(fresh);
        fresh.querySelectorAll("tr.finding").forEach(function (row) {
          if (!before[row.textContent.trim()]) {
            row.classList.add("fresh");
            window.setTimeout(function () { row.classList.remove("fresh"); }, 4000);
          }
        });
      })
      .catch(function () {})
      .then(function () {
        fetching = false;
        if (again) { again = false; refresh(); }
      });
  }

  function start() {
    source = new EventSource("/live/findings" + (lastId ? "?after=" + encodeURIComponent(lastId) : ""));
    source.addEventListener("change", function (event) {
      if (event.lastEventId) lastId = event.lastEventId;
      refresh();
    });
    toggle.textContent = "Pause live updates";
    toggle.setAttribute("aria-pressed", "true");
  }

  function stop() {
    if (source) source.close();
    source = null;
    toggle.textContent = "Resume live updates";
    toggle.setAttribute("aria-pressed", "false");
  }

  toggle.hidden = false;
  toggle.addEventListener("click", function () { if (source) stop(); else { start(); refresh(); } });
  start();
})();
