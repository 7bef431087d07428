"""See the arm: a live 3D view, plots, state and controls in the browser (the ``view`` extra: viser).

::

    akarm view robots/arm6.yaml                    # the arm a running `akarm serve` drives
    akarm serve robots/arm6.yaml --view            # the server, its view drawn by a process of its own
    akarm sim robots/arm6.yaml --view              # the simulated truth
    akarm demo --view                              # the demo session, watched
    akarm view robots/arm6.yaml --play run.csv     # a recorded run, with a time slider

From Python (``ViewServer`` instead draws in this process's threads, which costs the loop slots)::

    from akarm.view import ViewProcess, ArmSource
    with ViewProcess(arm.config, ArmSource(arm)) as view:
        print(view.url)
        arm.move_to("ready")

- :mod:`akarm.view.page`: :class:`ViewServer`, the page (viser) and its drawing thread;
- :mod:`akarm.view.process`: :class:`ViewProcess`, the same page drawn by a child process that the
  loop's process only feeds snapshots (``--view``): the way to watch a loop that must keep time;
- :mod:`akarm.view.sources`: where snapshots come from (a server here or over its socket, an Arm,
  a simulator), and the controls of a server;
- :mod:`akarm.view.recorded`: telemetry files played back (readers by suffix);
- :mod:`akarm.view.figure`, :mod:`akarm.view.visuals`: what is drawn (the URDF's visuals, or a figure
  from the kinematics); :mod:`akarm.view.history`, :mod:`akarm.view.panel`: the plots' data and the
  state panel.

Only :mod:`akarm.view.page` needs viser (imported when a view starts); the rest is plain numpy,
Pinocchio and trimesh (viser's dependency, for shapes and meshes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akarm.view.page import ViewServer
    from akarm.view.process import ViewProcess
    from akarm.view.recorded import RecordedSource
    from akarm.view.sources import ArmSource, Controls, RemoteSource, ServerSource, SimSource

__all__ = ["ArmSource", "Controls", "RecordedSource", "RemoteSource", "ServerSource", "SimSource", "ViewProcess",
           "ViewServer"]

_WHERE = {"ViewServer": "akarm.view.page", "ViewProcess": "akarm.view.process",
          "RecordedSource": "akarm.view.recorded", "ArmSource": "akarm.view.sources",
          "Controls": "akarm.view.sources", "RemoteSource": "akarm.view.sources", "ServerSource": "akarm.view.sources",
          "SimSource": "akarm.view.sources"}


def __getattr__(name: str) -> Any:  # the CLI imports akarm.view lightly; the modules load when used
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'akarm.view' has no attribute {name!r}")
