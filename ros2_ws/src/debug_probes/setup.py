from setuptools import find_packages, setup

package_name = "debug_probes"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="Robot-side debug probes: image debug drawings and a JPEG compressor that "
                "cost nothing while nobody looks.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "jpeg_compressor = debug_probes.compressor:main",
        ],
        "efficient_comm.components": [
            "debug_probes::JpegCompressor = debug_probes.compressor:JpegCompressor",
        ],
    },
)
