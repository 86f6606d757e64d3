// The query page's example menu: choosing an example puts its text into the editor at once (the "Load into
// the editor" button does the same through the server, for browsers without JavaScript), and the editor's
// form carries the choice so the menu still shows it on the answer page.
(function () {
  "use strict";
  var menu = document.getElementById("example-menu");
  var editor = document.getElementById("query-editor");
  var chosen = document.getElementById("query-example");
  if (!menu || !editor) {
    return;
  }
  menu.addEventListener("change", function () {
    var option = menu.options[menu.selectedIndex];
    if (option && option.dataset.query !== undefined) {
      editor.value = option.dataset.query;
      if (chosen) { chosen.value = option.value; }
      editor.focus();
    }
  });
})();
