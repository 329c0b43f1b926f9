"""The sorting cell's sorter agent."""
