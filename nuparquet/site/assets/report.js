// nuparquet report: sortable and filterable tables, hand-written, no library, no network.
"use strict";

function cellValue(row, column) {
  const cell = row.cells[column];
  const key = cell.dataset.sort !== undefined ? cell.dataset.sort : cell.textContent.trim();
  const number = Number(key);
  return key !== "" && !Number.isNaN(number) ? number : key.toLowerCase();
}

function sortTable(table, column, descending) {
  const body = table.tBodies[0];
  const rows = Array.from(body.rows);
  rows.sort((a, b) => {
    const x = cellValue(a, column), y = cellValue(b, column);
    const order = typeof x === typeof y ? (x < y ? -1 : x > y ? 1 : 0) : (typeof x === "number" ? -1 : 1);
    return descending ? -order : order;
  });
  rows.forEach((row) => body.appendChild(row));
  Array.from(table.tHead.rows[0].cells).forEach((th, i) => {
    if (i === column) th.setAttribute("aria-sort", descending ? "descending" : "ascending");
    else th.removeAttribute("aria-sort");
  });
}

function filterTable(table, text, location) {
  const words = text.toLowerCase().split(/\s+/).filter((w) => w);
  let shown = 0;
  Array.from(table.tBodies[0].rows).forEach((row) => {
    const haystack = row.textContent.toLowerCase();
    const visible = words.every((w) => haystack.includes(w)) && (!location || row.dataset.location === location);
    row.hidden = !visible;
    shown += visible ? 1 : 0;
  });
  return shown;
}

document.addEventListener("DOMContentLoaded", () => {
  document.querySelectorAll("table.sortable").forEach((table) => {
    Array.from(table.tHead.rows[0].cells).forEach((th, column) => {
      th.addEventListener("click", () => sortTable(table, column, th.getAttribute("aria-sort") === "ascending"));
    });
  });
  const table = document.getElementById("scene-table");
  const text = document.getElementById("scene-filter");
  const location = document.getElementById("location-filter");
  const count = document.getElementById("scene-count");
  if (table && text && location && count) {
    const update = () => { count.textContent = filterTable(table, text.value, location.value); };
    text.addEventListener("input", update);
    location.addEventListener("change", update);
    update();
  }
});
