"""The sorting cell's conveyor agent."""
