"""The live demo server (viser): scene, controls, image panels and plots over a bounded history
of frame records. Entry: :func:`tileviz.app.serve_cli.main` (``python -m tileviz serve``)."""
