"""Planted faults for the exact interface check: each module holds an a_pl that
differs from its interface in the specification in one way. None starts: each is refused."""
