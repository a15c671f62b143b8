"""The dask worker plugin that installs a sweep's context on every worker (imported only when dask runs).

A plugin, rather than a task argument, so that the context (the cycle maps,
about 20 MB, and the scenario setups) travels once per worker, not once per
batch, and so that a worker that joins later or that the nanny restarts after
a crash gets it too.
"""

from __future__ import annotations

from distributed.diagnostics.plugin import WorkerPlugin

from evtms.system.sweep import SweepContext, install, uninstall


class SweepPlugin(WorkerPlugin):
    """Installs :class:`~evtms.system.sweep.SweepContext` ``context`` in a worker; forgets it on teardown."""

    def __init__(self, context: SweepContext) -> None:
        self.context = context
        self.name = f"evtms-sweep-{context.token}"

    def setup(self, worker: object) -> None:
        install(self.context)

    def teardown(self, worker: object) -> None:
        uninstall(self.context.token)


def register(client, context: SweepContext) -> SweepPlugin:
    """Install ``context`` on every worker of ``client`` (and on the ones that join later)."""
    plugin = SweepPlugin(context)
    client.register_plugin(plugin, name=plugin.name)
    return plugin


def unregister(client, plugin: SweepPlugin) -> None:
    """Remove the plugin: each worker forgets the context."""
    try:
        client.unregister_worker_plugin(plugin.name)
    except (OSError, ValueError, KeyError):  # the cluster is going away already (Ctrl-C): nothing to forget
        pass
