"""The agents of the Robot Companion (paper §5), one package each, one process each: a_hi
(human_interface), a_co (coordinator), a_pl (planner), a_km (knowledge), a_ta (task_executor)
and ag_ex's communication side (executor). Each subclasses services.runtime.agent.Agent; the
specification names each one's implementation. They import the runtime and the codec, never a
tool nor one another (tests/architecture)."""
