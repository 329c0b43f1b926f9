"""The sorting cell's agents and content terms (examples/sorting_cell/README.md)."""
