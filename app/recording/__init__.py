"""Event clips (H.264 in MP4), the pre-roll they start from, and activity history."""
