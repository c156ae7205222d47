"""See the motion: a self-contained HTML preview, a PNG contact sheet, and a streaming server."""
