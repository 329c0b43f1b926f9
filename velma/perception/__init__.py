"""Perception from the head's depth camera: what Velma sees for itself.

The library, bottom up (one job a module):

- ``noise``: the first-generation Kinect's depth errors (random error, disparity
  quantisation, missing depth at grazing incidence and out of range), pure numpy.
- ``kinect``: the head camera as that Kinect: renders RGB and metric depth of a simulation
  state off-screen with MuJoCo, applies ``noise``, returns a ``DepthFrame`` with the
  intrinsics and the camera's world pose from the robot's own head kinematics.
- ``cloud``: back-projection of a frame to a coloured world point cloud, and depth-image normals.
- ``objects``: the known objects' models (surface samples in the body frame, colour, size),
  derived from the kitchen model's geoms — the CAD model and appearance a real system has.
- ``localise``: segments each requested object in a point cloud (support plane, height band,
  clustering, size and colour) and fits its model with ICP (small_gicp).
- ``content``: estimates how many content spheres a container holds from what is visible.

None of it reads MuJoCo's state of the objects (body poses, geom ids, segmentation renders):
only the rendered pixels, the head's pose and the objects' models.
"""
