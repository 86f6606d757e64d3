// The query page's example menu: choosing an example puts its text into the editor at once (the "Load into
// the editor" button does the same through the server, for browsers without JavaScript).
(function () {
  "use strict";
  var menu = document.getElementById("example-menu");
  var editor = document.getElementById("query-editor");
  if (!menu || !editor) {
    return;
  }
  menu.addEventListener("change", function () {
    var option = menu.options[menu.selectedIndex];
    if (option && option.dataset.query !== undefined) {
      editor.value = option.dataset.query;
      editor.focus();
    }
  });
})();
