"""The specification's checkers and derivations (design.md layer 5: above the runtime, never
imported by it): the router's access control (acl), conformance of recorded traffic
(conformance, causal), deadlock freedom of the protocols (deadlock) and the code check
(code_check)."""
