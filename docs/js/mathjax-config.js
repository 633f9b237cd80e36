// MathJax 3 for pymdownx.arithmatex's generic output, served from the site itself (no CDN):
// docs/js/mathjax/tex-svg.js is MathJax 3.2.2's TeX-to-SVG bundle, fonts included.
window.MathJax = {
  tex: {inlineMath: [["\\(", "\\)"]], displayMath: [["\\[", "\\]"]], processEscapes: true},
  svg: {fontCache: "global"},
  options: {ignoreHtmlClass: ".*|", processHtmlClass: "arithmatex"},
};
