"""``roco sniff``: live communicates as they cross Zenoh, in FIPA SC00070 string form
(services/sniff/sniffer.py; the command: services/cli/sniff.py)."""
