"""Install hints match how stereodyn was installed (issue 32): a checkout's `pip install '.[X]'`, a distribution's
`pip install 'stereodyn[X]'`. The adapters' reasons use the same hint (tests/helpers.py
assert_skipped_without_sdk, tests/test_engine_catalog.py)."""
from stereodyn.harness import install


def test_a_checkout_hints_its_own_folder(monkeypatch, tmp_path):
    root = install.checkout()
    assert root is not None and (root / "pyproject.toml").is_file()  # the tests run from the source tree
    monkeypatch.chdir(root)
    assert install.hint("bullet") == "pip install '.[bullet]'"
    monkeypatch.chdir(tmp_path)  # elsewhere, the checkout's path: '.' would name the wrong folder
    assert install.hint("bullet") == f"pip install '{root}[bullet]'"


def test_a_distribution_hints_the_package(monkeypatch):
    monkeypatch.setattr(install, "checkout", lambda: None)
    assert install.hint("mjx") == "pip install 'stereodyn[mjx]'"

