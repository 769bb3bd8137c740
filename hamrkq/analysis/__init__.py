"""Analysis of a solution: diagnostics, independent references, comparisons."""
