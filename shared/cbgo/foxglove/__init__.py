"""cbgo data for Foxglove: JSON channels with schemas, and derived 3D scene, transforms and log.

One conversion, used by ``cbgo export``, ``cbgo record --encoding json`` and the live bridge
(``cbgo foxglove``, the foxglove-bridge service) alike:

- `channels`: each wire key becomes a JSON channel (topic = the key, schema from
  `cbgo.json_schema`); `JsonChannels` writes them and the derived ones into MCAP;
- `derive`: `Deriver` turns the wire messages into ``foxglove.SceneUpdate`` (hands, objects,
  TCP, focus ray, the target highlighted), ``foxglove.FrameTransforms`` (base and Leap frame)
  and ``foxglove.Log`` (episode, intent and plan events);
- `scene`: the scene entities themselves, pure functions of wire messages.

Foxglove's schemas are vendored in ``schemas/`` with their MIT licence. Nothing here imports
the foxglove-sdk package; only the bridge service does.
"""
