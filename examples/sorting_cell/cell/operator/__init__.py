"""The sorting cell's operator agent."""
