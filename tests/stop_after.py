"""A simulated observer that presses Ctrl-C at a given trial: the tests' interrupted-then-resumed sessions."""

from __future__ import annotations

from tactilab.experiments import SimulatedObserver


class StopAfter(SimulatedObserver):
    """The same simulated observer, with Ctrl-C pressed at trial ``stop_at`` (not part of its config)."""

    stop_at = None

    def collect(self, plan):
        if plan.trial_index == self.stop_at:
            raise KeyboardInterrupt("test stop")
        return super().collect(plan)
