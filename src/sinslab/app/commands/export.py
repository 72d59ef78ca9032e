"""``sinslab export RUN --to kml|geojson``: a run's track with its GNSS fixes and outages
as a file for Google Earth, QGIS or a web map (:mod:`sinslab.app.export`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

from sinslab.app.commands.runner import cli_call

__all__ = ["register"]


def register(app: Any) -> Any:
    """Add the ``sinslab export`` command to the typer ``app`` (called from sinslab.cli)."""
    import typer

    @app.command()
    def export(run: Path = typer.Argument(..., metavar="RUN", help="run folder (navigate, or an experiment with a track)"),
               to: str = typer.Option(..., "--to", help="kml | geojson"),
               out: Optional[Path] = typer.Option(None, "--out", "-o",
                                                  help="file to write [default: beside the run, RUN.kml / RUN.geojson]")) -> None:
        """Write a run's track, GNSS fixes and outages as KML or GeoJSON."""
        from sinslab.app.export import export_run

        path = cli_call(export_run, run, to, out)
        typer.echo(str(path))

    return export
