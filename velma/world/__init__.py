"""The simulated robot's hardware beside the kitchen: what a real Velma has on its own side of
the controller (joint encoders and torque inputs, wrist force/torque sensors, the hands' and the
head's servos, the head camera's capture), and the link its controller talks to it through
(``velma.world.link``)."""
