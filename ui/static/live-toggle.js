// The "Live updates" button of a live page: the stream `open()` opens (an EventSource, from wherever the page
// has got to) is on at first; the button pauses it (closing it) and resumes it (opening it again).
window.segbLiveToggle = function (toggle, open) {
  "use strict";
  var source = null;

  function start() {
    source = open();
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
};
