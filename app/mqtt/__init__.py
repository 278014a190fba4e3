"""MQTT and Home Assistant: Vigil's cameras on a broker (``docs/mqtt.md``).

``broker``: the broker's address from ``VIGIL_MQTT_URL``; ``topics``: the topic names;
``discovery``: Home Assistant's discovery payloads; ``mirror``: what the broker should
hold, kept from the event bus and the cameras' state; ``bridge``: the asyncio tasks that
connect, publish and take commands.
"""
