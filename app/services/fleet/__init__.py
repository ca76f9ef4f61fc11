"""The fleet at a glance: every live tool's row and why it needs attention (fleet), which
TCP each row's robot moves by, as SQL (live), its gauges (gauges) read by /metrics at
scrape (collector), and what the plant is shown over OPC UA (plant).
"""
