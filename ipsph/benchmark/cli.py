"""`ipsph bench` (being written)."""


def add_arguments(p):
    pass


def main(args) -> int:
    raise SystemExit("ipsph bench: not implemented yet")
