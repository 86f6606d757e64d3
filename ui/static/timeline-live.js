// Feeds the /timeline page's viewer (/timeline/viewer.js): the first page of events is in the page; the rest of
// the window is fetched page by page from this UI (/timeline/data, which asks the API with the viewer's token),
// and the API's live stream (relayed at /live/timeline) replaces the events a robot's posts change. A button
// pauses and resumes the stream; resuming replays what changed meanwhile.
(function () {
  "use strict";
  var root = document.getElementById("timeline");
  if (!root || !window.SEGBTimeline) return;
  var progress = document.getElementById("timeline-progress");
  var toggle = document.getElementById("live-toggle");
  var PAGE = 5000; // events per fetch
  var MOST = 250000; // events the page holds at most: past that, a narrower window shows the rest
  var timeline = window.SEGBTimeline.mount(root);
  var first = document.getElementById(root.getAttribute("data-first"));
  var loaded = 0;

  function say(text) { if (progress) progress.textContent = text; }
  function count(n) { return n.toLocaleString("en"); }

  function add(rows) {
    loaded += rows.length;
    timeline.append(rows);
  }

  function more(next) {
    if (!next) {
      timeline.finished();
      say(count(loaded) + " events in this window");
      return;
    }
    if (loaded >= MOST) {
      timeline.finished();
      say("The first " + count(loaded) + " events of this window are shown; narrow the window to see the rest.");
      return;
    }
    say("Loading… " + count(loaded) + " events so far");
    var url = root.getAttribute("data-source") + "&limit=" + PAGE + "&after=" + encodeURIComponent(next);
    fetch(url, { credentials: "same-origin", headers: { Accept: "application/json" } })
      .then(function (answer) {
        if (!answer.ok) throw new Error("status " + answer.status);
        return answer.json();
      })
      .then(function (page) {
        add(page.rows);
        more(page.has_more ? page.next : null);
      })
      .catch(function (error) {
        timeline.finished();
        say("Loading stopped after " + count(loaded) + " events (" + error.message + "); reload the page to try again.");
      });
  }

  function reload() {
    // The changes since the page's rows are no longer known: everything is read again.
    timeline.clear();
    loaded = 0;
    say("Reading the timeline again…");
    fetch(root.getAttribute("data-source") + "&limit=" + PAGE, { credentials: "same-origin" })
      .then(function (answer) {
        if (!answer.ok) throw new Error("status " + answer.status);
        return answer.json();
      })
      .then(function (page) { add(page.rows); more(page.has_more ? page.next : null); })
      .catch(function () { say("The timeline could not be read again; reload the page."); });
  }

  add(first ? JSON.parse(first.textContent) : []);
  more(root.getAttribute("data-next"));

  // --- live updates ------------------------------------------------------------------------------------------
  if (!toggle || !window.EventSource || !window.segbLiveToggle) return;
  var lastId = root.getAttribute("data-after") || "";
  window.segbLiveToggle(toggle, function () {
    var source = new EventSource(root.getAttribute("data-live") + (lastId ? "&after=" + encodeURIComponent(lastId) : ""));
    source.addEventListener("rows", function (event) {
      lastId = event.lastEventId || lastId;
      var change = JSON.parse(event.data);
      timeline.upsert(change.kind, change.keys, change.rows);
    });
    source.addEventListener("reset", function () { reload(); });
    return source;
  });
})();
