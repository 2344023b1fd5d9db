"""A node that always crashes at start-up (exit code 1), without importing rclpy."""
import sys


def main(args=None) -> int:
    """Print a line and fail."""
    print('crash_node: failing on purpose', flush=True)
    return 1


if __name__ == '__main__':
    sys.exit(main())
