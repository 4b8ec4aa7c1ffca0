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


def test_a_distribution_hints_the_package(monkeypatch):  # noqa: D103
    monkeypatch.setattr(install, "checkout", lambda: None)
    assert install.hint("mjx") == "pip install 'stereodyn[mjx]'"



def test_a_plain_install_from_a_checkout_hints_that_checkout(monkeypatch, tmp_path):
    """`pip install '.[drake]'` (the README's main command) copies the package; PEP 610's direct_url.json names the
    folder it came from (measured: a fresh clone's run hinted 'stereodyn[engines]' before this)."""
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "stereodyn"\n')
    monkeypatch.setattr(install, "_installed_from", lambda: tmp_path)
    monkeypatch.setattr(install, "__file__", str(tmp_path / "site" / "stereodyn" / "harness" / "install.py"))
    install.checkout.cache_clear()
    try:
        assert install.checkout() == tmp_path
        monkeypatch.chdir(tmp_path)
        assert install.hint("engines") == "pip install '.[engines]'"
    finally:
        install.checkout.cache_clear()
