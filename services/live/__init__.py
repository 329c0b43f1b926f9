"""The live view of ``roco run``, ``roco scenario`` and ``roco chaos`` on a terminal:
under the event lines, the command, plan k of n, the step running and its place in the plan,
agents alive, simulated against wall time, and the control loop's overrun share.

All of it is read from what the run already observes, no new message: the communicates on
``roco/fipa/**`` (C2 commands, C3 plan requests and plans, C1 a_ta's L_SW states), ag_ex's
``roco/state/ag_ex`` (sim time, loop timing) and the liveliness tokens ``roco/alive/*``.

- services/live/state.py: ``LiveState``, the fold of those observations (no I/O);
- services/live/view.py: ``LiveView``, the rich renderable of one state;
- services/live/watch.py: ``LiveWatch``, the Zenoh subscribers and the rich ``Live`` display.
"""
