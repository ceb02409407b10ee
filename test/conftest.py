"""Shared by every test: this folder is on ``sys.path`` (pytest puts a rootdir conftest's
folder there), so test modules import the scene builders in ``scene_builders`` and the
numerical helpers in ``helpers`` without path changes of their own. The package itself is
imported from where it is installed (``scripts/test.sh`` runs pytest with ``-I``)."""
