"""`stereodyn matrix`: placeholder."""


def main(args) -> int:
    raise NotImplementedError
