"""Notifications: an event's start told to people wherever they are, through Apprise URLs
(e-mail, Telegram, ntfy, Gotify, Pushover, Discord, Slack, Matrix, JSON webhooks...).

``targets``: Apprise as Vigil uses it (a URL checked, masked, sent to); ``message``: what
an alarm's message says; ``notifier``: the bus listener and a worker thread per target.
docs/notifications.md says how to use it.
"""
