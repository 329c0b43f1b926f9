"""The specification's checkers and derivations (a tool: above the runtime, never imported by
it; README.md "How it is built", tests/architecture/test_import_graph.py): the router's access
control (acl), conformance of recorded traffic (conformance, causal), deadlock freedom of the
protocols (deadlock) and the code check (code_check)."""
